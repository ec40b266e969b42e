"""Generate the cffi API-mode wrapper of the MCAHRS C core.

The cdef is the real public header, run through the C preprocessor with empty stand-ins
for the standard headers (cffi knows the fixed-width types itself), so the declarations
can never drift from the C. Integer ``#define MCA_*`` constants of the headers are added
as ``#define NAME ...`` so Python reads their values from the compiled C, not a copy.

CMake runs this (bindings/CMakeLists.txt); it only writes C source, it compiles nothing.
"""

from __future__ import annotations

import argparse
import re
import subprocess
import tempfile
from pathlib import Path

import cffi

UMBRELLA = "mcahrs/mcahrs.h"
STD_HEADERS = ("stdint.h", "stddef.h", "stdbool.h")
# Object-like MCA_* macros with an integer value (literals or integer expressions such as
# MCA_CS_WS_LEN); float macros (with a '.') and function-like macros are left out.
INT_DEFINE = re.compile(r"^#define\s+(MCA_[A-Z0-9_]+)[ \t]+([^.\n]*?)\s*(?:/\*.*)?$", re.M)


def preprocess(cc: str, include: Path) -> str:
    with tempfile.TemporaryDirectory() as fake:
        for h in STD_HEADERS:
            Path(fake, h).write_text("")
        out = subprocess.run(
            [cc, "-E", "-P", "-nostdinc", "-I", fake, "-I", str(include), "-x", "c", "-"],
            input=f'#include "{UMBRELLA}"\n',
            capture_output=True,
            text=True,
            check=True,
        ).stdout
    return out


def constants(include: Path) -> list[str]:
    names: list[str] = []
    for h in sorted((include / "mcahrs").glob("*.h")):
        names += [n for n, body in INT_DEFINE.findall(h.read_text()) if body and not body.startswith('"')]
    return [f"#define {n} ..." for n in dict.fromkeys(names)]


def build_ffi(cc: str, include: Path) -> cffi.FFI:
    ffi = cffi.FFI()
    ffi.cdef(preprocess(cc, include) + "\n" + "\n".join(constants(include)))
    ffi.set_source("mcahrs._mcahrs_cffi", f'#include "{UMBRELLA}"', include_dirs=[str(include)])
    return ffi


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cc", default="cc")
    ap.add_argument("--include", type=Path, required=True)
    ap.add_argument("--out", type=Path, required=True)
    a = ap.parse_args()
    build_ffi(a.cc, a.include).emit_c_code(str(a.out))


if __name__ == "__main__":
    main()
