#!/usr/bin/env python3
"""Per-function instruction profile of one core entry point on the emulated Cortex-M4F.

    python scripts/fw_profile.py [--entry mca_nav_gps] [--vector tests/vectors/nav_turns.mcav]
                                 [--build build/fw] [--top 25] [--lines F] [--exclude F] [--calls] [--call K]

Runs the firmware replay image (``scripts/fw_report.py`` builds it) on ``qemu-system-arm -M
mps2-an386 -icount shift=0`` with QEMU's translation and execution logs
(``-d in_asm,exec,nochain``), streamed through a pipe, never written to disk. Each executed
translation block is credited with its guest instruction count to the function that holds its
address (``arm-none-eabi-nm``). Only blocks executed inside a call of ``--entry`` are counted:
from its first instruction until it returns, followed on a shadow call stack (a block at a
function's first instruction, reached from another function, is a call; a block of a function
further down the stack is a return to it, so a tail call, which returns to its caller's caller,
ends where it should; the LTO firmware tail-calls ``yaw_obs``). The
entry may be any function of the image, static ones included (``--entry gps_cs``: the CS part of
the GPS step), if it is not recursive. It prints where the entry's instructions go, per call and
by function (each function's own instructions), the way callgrind does on the host, but with the
target's code (-Os Thumb-2, FPv4). ``--lines F`` splits function F's own instructions by source
line; that needs a build with line tables (configure a copy with ``CFLAGS=-g``, which changes no
instruction, and pass ``--build``). ``--exclude F`` leaves out F's calls inside the entry,
with everything they call (``--entry mca_nav_gps --exclude yaw_obs``: the GPS step without the
course-over-ground update, the part the issue's <= 12,000 goal names). The first line gives the
mean, min and max of the calls; ``--calls`` prints every call's count, ``--call K`` profiles the
K-th call alone (where a maximum goes).

It reports; it asserts nothing. Its per-call totals are comparable with fw_report.py's SysTick
counts, which also include the call and its argument set-up; both count every executed
instruction (QEMU ``-icount``), a block cut short by an I/O access is credited whole here.
"""

from __future__ import annotations

import argparse
import bisect
import re
import subprocess
import sys
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

IN_RE = re.compile(r"^IN: ")
INSN_RE = re.compile(r"^0x([0-9a-f]+):\s")
TRACE_RE = re.compile(r"^Trace \d+: (0x[0-9a-f]+) \[[0-9a-f]+/([0-9a-f]+)/")


def symbols(elf: Path) -> tuple[list[int], list[str], list[int]]:
    """Function start addresses (sorted), names and sizes from the image's symbol table."""
    out = subprocess.run(
        ["arm-none-eabi-nm", "-n", "--print-size", str(elf)], check=True, capture_output=True, text=True
    ).stdout
    starts: list[int] = []
    names: list[str] = []
    sizes: list[int] = []
    for line in out.splitlines():
        parts = line.split()
        if len(parts) == 4 and parts[2] in ("t", "T", "W"):
            starts.append(int(parts[0], 16) & ~1)
            sizes.append(int(parts[1], 16))
            names.append(parts[3])
    return starts, names, sizes


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--entry", default="mca_nav_gps", help="entry point whose calls are profiled")
    ap.add_argument("--vector", type=Path, default=ROOT / "tests/vectors/nav_turns.mcav")
    ap.add_argument("--build", type=Path, default=ROOT / "build/fw", help="firmware build directory")
    ap.add_argument("--top", type=int, default=25, help="functions (or lines) to print")
    ap.add_argument("--lines", metavar="FUNCTION", help="split FUNCTION's own instructions by source line")
    ap.add_argument(
        "--exclude", metavar="FUNCTION",
        help="leave out FUNCTION's calls (with all they call) inside the entry, e.g. --entry mca_nav_gps "
        "--exclude yaw_obs: the GPS step without the course update",
    )  # fmt: skip
    ap.add_argument("--calls", action="store_true", help="also print each call's count (to find the longest)")
    ap.add_argument("--call", type=int, help="profile only the call with this index (0-based, see --calls)")
    args = ap.parse_args()

    elf = args.build / "fw.elf"
    if not elf.exists():
        print(f"error: {elf} not found; scripts/fw_report.py builds it", file=sys.stderr)
        return 2
    starts, names, sizes = symbols(elf)
    try:
        entry = starts[names.index(args.entry)]
        excl = starts[names.index(args.exclude)] if args.exclude else -1
    except ValueError:
        print(f"error: {args.entry} or {args.exclude} is not a function of {elf}", file=sys.stderr)
        return 2

    def func_at(pc: int) -> int:
        i = bisect.bisect_right(starts, pc) - 1
        return i if i >= 0 and pc < starts[i] + max(sizes[i], 2) else -1

    cmd = [
        "qemu-system-arm", "-M", "mps2-an386", "-nographic", "-monitor", "none", "-serial", "none",
        "-icount", "shift=0", "-semihosting-config", "enable=on,target=native", "-kernel", str(elf),
        "-d", "in_asm,exec,nochain", "-D", "/dev/stderr",
        "-append", f"{args.vector} /dev/null",
    ]  # fmt: skip
    proc = subprocess.Popen(cmd, stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True, cwd=ROOT)
    assert proc.stderr is not None
    tb_len: dict[str, int] = {}  # host TB pointer -> guest instructions of the block
    pending: list[int] = []  # instruction addresses of the block just translated
    self_count: Counter[int] = Counter()
    pc_count: Counter[int] = Counter()  # --lines: instructions by address inside that function
    line_func = names.index(args.lines) if args.lines in names else -1
    if args.lines and line_func < 0:
        print(f"error: {args.lines} is not a function of {elf}", file=sys.stderr)
        return 2
    tb_pcs: dict[str, list[int]] = {}
    calls = 0
    per_call: list[int] = []  # instructions of each call
    # A shadow call stack of functions: a block at a function's first instruction entered from
    # another function is a call (a tail call too: b.w to it); a block inside a function below
    # the top, not at its start, is a return to it (tail-called code returns to its caller's
    # caller). A call of --entry lasts while its frame is on the stack, and so does an
    # excluded call of --exclude.
    stack: list[int] = []
    entry_depth = excl_depth = -1  # stack depth of the entry's / excluded call's frame, -1: none
    entry_func, excl_func = func_at(entry), func_at(excl) if excl >= 0 else -1
    prev_func = -1
    for line in proc.stderr:
        if IN_RE.match(line):
            pending = []
            continue
        m = INSN_RE.match(line)
        if m:
            pending.append(int(m.group(1), 16))
            continue
        m = TRACE_RE.match(line)
        if not m:
            continue
        host, pc = m.group(1), int(m.group(2), 16)
        if pending and pending[0] == pc:
            tb_len[host] = len(pending)  # the first execution of a freshly translated block
            tb_pcs[host] = pending
            pending = []
        n = tb_len.get(host, 1)
        f_now = func_at(pc)
        if f_now != prev_func:
            if f_now >= 0 and pc == starts[f_now]:
                stack.append(f_now)  # a call (or tail call) of f_now
                if pc == entry and entry_depth < 0:
                    entry_depth = len(stack) - 1
                    calls += 1
                    per_call.append(0)
                elif pc == excl and entry_depth >= 0 and excl_depth < 0:
                    excl_depth = len(stack) - 1
            elif f_now in stack:
                while stack[-1] != f_now:  # a return, through any tail-called frames
                    stack.pop()
            else:
                stack = [f_now]  # code the stack has not seen enter (startup, replay)
        if excl_depth >= len(stack) or (excl_depth >= 0 and stack[excl_depth] != excl_func):
            excl_depth = -1
        if entry_depth >= len(stack) or (entry_depth >= 0 and stack[entry_depth] != entry_func):
            entry_depth = -1
        prev_func = f_now
        if entry_depth >= 0 and excl_depth < 0 and (args.call is None or calls - 1 == args.call):
            f = f_now
            self_count[f] += n
            per_call[-1] += n
            if f == line_func:
                for a in tb_pcs.get(host, [pc]):
                    pc_count[a] += 1
    rc = proc.wait()
    if rc != 0:
        print(f"error: QEMU exited with {rc}", file=sys.stderr)
        return 3
    if calls == 0:
        print(f"{args.entry} was never called by {args.vector.name}", file=sys.stderr)
        return 1
    if args.calls:
        print("instructions of each call, in order:", " ".join(str(c) for c in per_call))
    total = sum(self_count.values())
    if args.call is not None:
        calls = 1  # one call profiled: its own figures
    without = f" without {args.exclude}" if args.exclude else ""
    spread = f"min {min(per_call)}, max {max(per_call)}"
    print(f"{args.entry}{without}: {calls} calls in {args.vector.name}, {total / calls:.0f} instructions "
          f"per call ({spread}; self, by function, per call; {elf})")  # fmt: skip
    print(f"  {'function':34s} {'per call':>9s} {'share':>7s}")
    for f, c in self_count.most_common(args.top):
        name = names[f] if f >= 0 else "?"
        print(f"  {name:34s} {c / calls:9.0f} {100.0 * c / total:6.1f}%")
    if line_func >= 0:
        print_lines(elf, pc_count, calls, args.top)
    return 0


def print_lines(elf: Path, pc_count: Counter[int], calls: int, top: int) -> None:
    """Instructions per call by source line (addr2line), most expensive first."""
    pcs = sorted(pc_count)
    out = subprocess.run(
        ["arm-none-eabi-addr2line", "-e", str(elf)], input="\n".join(f"{a:x}" for a in pcs),
        check=True, capture_output=True, text=True,
    ).stdout.splitlines()  # fmt: skip
    by_line: Counter[str] = Counter()
    for a, loc in zip(pcs, out, strict=True):
        by_line[loc.split("/")[-1].split(" ")[0]] += pc_count[a]
    total = sum(by_line.values())
    print(f"  by source line ({total / calls:.0f} per call):")
    for loc, c in by_line.most_common(top):
        print(f"    {loc:34s} {c / calls:9.0f} {100.0 * c / total:6.1f}%")


if __name__ == "__main__":
    sys.exit(main())
