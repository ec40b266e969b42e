"""`python -m mcahrs ...` is the `mcahrs` command."""

from mcahrs.cli import main

raise SystemExit(main())
