"""Float64 NumPy golden model of the MCAHRS core, written from DESIGN.md and ALGORITHMS.md.

Independent of the C core (it never reads or calls it); one file per C module:
``robust`` (the measurement update, ALGORITHMS.md 1) and ``cs`` (the current-statistical
maneuver filter, ALGORITHMS.md 2-3).
"""
