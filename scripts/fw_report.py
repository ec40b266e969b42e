#!/usr/bin/env python3
"""Cost report of the Cortex-M4F build: flash/RAM, stack, instructions, CPU share.

    python scripts/fw_report.py [--cpi 1.25] [--mhz 168] [--imu-hz 400] [--gps-hz 10] [--ins-gps-hz 5]

Builds ``c_core/firmware`` for the M4F (build/fw, -Os; ``--build-type Release``: build/fw-Release,
-O2), replays every golden vector file
(``tests/vectors/*.mcav``) on ``qemu-system-arm -M mps2-an386 -icount shift=0`` and prints,
beside the goals (it reports, it does not assert):

1. flash and RAM of the core alone (``mca_core_nav.elf``: the functions of ``mca_nav.h``
   as roots, with what they pull from libm/libc/libgcc; ``mca_core_only.elf``: every public
   function), per object from the map file, and of the whole replay image;
2. worst-case stack of every public function: ``-fstack-usage`` frames (``.su``) plus the
   call graph of the linked image (``bl``/tail-call targets in ``objdump -d``; frames of
   library functions from their prologues), beside the painted high-water measured in QEMU;
3. executed instructions per call of each measured entry point (exact: see
   c_core/firmware/README.md), mean and max, and the CPU share at the given clock and CPI;
4. the loosely-coupled INS (mca_ins.h, the reference filter) beside the CS + gravity navigation
   filter (mca_nav.h): state RAM, flash, worst stack and instructions of the IMU and GNSS steps,
   and the CPU share of each at the given clock for --imu-hz IMU + --ins-gps-hz GNSS;
5. host vs QEMU agreement of the outputs (real libm to tolerance, pinned libm bit for bit).
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
import tempfile
from collections import defaultdict
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import gen_vectors as gv  # noqa: E402

GOAL_FLASH = 24 * 1024
GOAL_STATE = 4 * 1024
GOAL_STACK = 1024
GOAL_INSTR = {"nav_imu": 2500, "nav_gps": 12000}
# Vector files that run a robust profile (gen_vectors.py), by profile: their calls are reported on
# their own, beside the goals, which are the base filter's (plain mode: three CS axes + gravity update).
ROWS_PROFILE = "the fuzzy-rows profile"
ROBUST_VECTORS = {
    ROWS_PROFILE: (
        "nav_outliers",
        "nav_outliers_rx",
        "nav_rows_taken_2hz",
        "nav_rows_release_2hz",
        "nav_rows_jitter",
    ),
    "the whole-update modes (FTA, AKF, fuzzy reject and inflate, IGG-III)": ("nav_modes",),
    "the INS's fuzzy detector under GNSS faults (100 Hz IMU)": ("ins_outliers",),
}
KIB = 1024.0


def ok(value: float, goal: float) -> str:
    return "ok" if value <= goal else "OVER"


# ----------------------------------------------------------------------------- sizes from the map


LTRANS_RE = re.compile(r"ltrans\d*\.ltrans\.o$")
# .text.NAME, .text.unlikely.NAME, .rodata.NAME, ... and the suffixes of GCC's clones
SECTION_SYM_RE = re.compile(r"^\.(?:text(?:\.unlikely|\.hot|\.startup)?|rodata|data|bss)\.(.+)$")
CLONE_RE = re.compile(r"\.(?:lto_priv|constprop|isra|part|cold)(?:\.\d+)?")


def lto_names(map_path: Path) -> dict[str, str]:
    """symbol -> "core <file>" for the sections of an LTO-linked image, whose map names the link's
    ltrans object as their origin: from the core archive's symbol tables (readelf: its fat
    objects also carry the ordinary code, static symbols included) and, for a static name that
    more than one file defines, the image's own .su lines (path:line:col:function)."""
    build = map_path.parent
    files: dict[str, set[str]] = defaultdict(set)
    archive = build / "mcahrs_core" / "libmcahrs_core.a"
    if archive.exists():
        out = subprocess.run(
            ["arm-none-eabi-readelf", "-sW", str(archive)], check=True, capture_output=True, text=True
        ).stdout
        member = None
        for line in out.splitlines():
            m = re.match(r"^File: .*\((.+?)\.obj\)$", line)
            if m:
                member = m.group(1)
                continue
            f = line.split()
            if member and len(f) >= 8 and f[3] in ("FUNC", "OBJECT") and f[6] != "UND":
                files[f[7]].add(member)
    names = {n: f"core {next(iter(fs))}" for n, fs in files.items() if len(fs) == 1}
    stem = map_path.name[: -len(".elf.map")] if map_path.name.endswith(".elf.map") else map_path.stem
    for su in build.glob(f"{stem}.ltrans*.ltrans.su"):
        for line in su.read_text().splitlines():
            loc = line.split("\t")[0]
            path, _, fn = loc.rpartition(":")
            src = Path(path.split(":")[0]).name
            base = CLONE_RE.sub("", fn)
            if src.endswith(".c") and base not in names:
                names[base] = f"core {src}"
    return names


def map_groups(map_path: Path, members: bool = False) -> dict[str, dict[str, int]]:
    """Bytes per object group (core file, libm, libc, libgcc, replay) and column (text, rodata,
    data, bss), from the input-section lines of a GNU ld map. In an LTO-linked image the core's
    sections come from the link's ltrans object; they are put back to their source file by the
    symbol each section holds (lto_names; one function or object a section, -ffunction-sections
    -fdata-sections at the LTO link), "core (LTO)" where no symbol names the section (constant
    pools)."""
    text = map_path.read_text()
    text = text[text.index("Linker script and memory map") :]
    flash_out = {".isr_vector", ".text", ".rodata", ".ARM.extab", ".ARM.exidx", ".init_array"}
    groups: dict[str, dict[str, int]] = defaultdict(lambda: defaultdict(int))
    out_sec, pending = None, None
    lto_box: list[dict[str, str]] = []  # lto_names(map_path), read at the first ltrans section

    def add(in_sec: str, size: int, origin: str) -> None:
        if out_sec in flash_out:
            col = "rodata" if in_sec.startswith(".rodata") else "text"
        elif out_sec == ".data":
            col = "data"
        elif out_sec == ".bss":
            col = "bss"
        else:
            return  # .stack, debug and other non-loaded sections
        if LTRANS_RE.search(origin):
            if not lto_box:
                lto_box.append(lto_names(map_path))
            m = SECTION_SYM_RE.match(in_sec)
            name = CLONE_RE.sub("", m.group(1)) if m else ""
            groups[lto_box[0].get(name, "core (LTO)")][col] += size
            return
        groups[member_of(origin) if members else group_of(origin)][col] += size

    for line in text.splitlines():
        m = re.match(r"^(\.\S+)", line)
        if m:
            out_sec, pending = m.group(1), None
            continue
        m = re.match(r"^ \*fill\*\s+0x[0-9a-f]+\s+0x([0-9a-f]+)", line)
        if m:
            add(".fill", int(m.group(1), 16), "*fill*")
            continue
        m = re.match(r"^ (\.\S+|COMMON)\s+0x[0-9a-f]+\s+0x([0-9a-f]+)\s+(\S.*)$", line)
        if m:
            add(m.group(1), int(m.group(2), 16), m.group(3))
            pending = None
            continue
        m = re.match(r"^ (\.\S+|COMMON)\s*$", line)
        if m:
            pending = m.group(1)
            continue
        m = re.match(r"^\s+0x[0-9a-f]+\s+0x([0-9a-f]+)\s+(\S.*)$", line)
        if m and pending:
            add(pending, int(m.group(1), 16), m.group(2))
            pending = None
    return groups


def group_of(origin: str) -> str:
    if origin == "*fill*":
        return "alignment padding"
    m = re.search(r"libmcahrs_core\.a\((.+?)\.obj\)", origin)
    if m:
        return f"core {m.group(1)}"
    for lib, name in (
        ("libm.a", "libm (newlib)"),
        ("libc_nano.a", "libc (newlib-nano)"),
        ("libgcc.a", "libgcc"),
    ):
        if lib + "(" in origin:
            return name
    return "replay/startup " + Path(origin.split("(")[0]).name


def member_of(origin: str) -> str:
    """Library member (lib_a-sf_sin.o -> libm sf_sin) or the group of anything else."""
    m = re.search(r"(libm|libc_nano|libgcc)\.a\((?:lib_a-)?(.+?)\.o\)", origin)
    return f"{m.group(1).replace('_nano', '')}:{m.group(2)}" if m else group_of(origin)


def print_groups(title: str, groups: dict[str, dict[str, int]]) -> int:
    print(f"  {title}")
    print(f"    {'object':32s} {'text':>7s} {'rodata':>7s} {'data':>6s} {'bss':>6s}")
    tot = defaultdict(int)
    order = sorted(groups, key=lambda g: (not g.startswith("core"), g))
    for g in order:
        c = groups[g]
        if not any(c.values()):
            continue
        print(f"    {g:32s} {c['text']:7d} {c['rodata']:7d} {c['data']:6d} {c['bss']:6d}")
        for k in ("text", "rodata", "data", "bss"):
            tot[k] += c[k]
    print(f"    {'total':32s} {tot['text']:7d} {tot['rodata']:7d} {tot['data']:6d} {tot['bss']:6d}")
    flash = tot["text"] + tot["rodata"] + tot["data"]
    return flash


# ----------------------------------------------------------------------------- stack


def su_frames(build: Path, image: str, funcs: dict[str, list[tuple[str, str]]]) -> dict[str, tuple[int, str]]:
    """function of the image -> (bytes, qualifier) from -fstack-usage: an LTO-linked image's own
    .su (<image>.ltrans*.ltrans.su, the code its link generated), else the core objects'. An LTO
    .su names a function without the number of its clone or LTO-private copy (align for
    align.lto_priv.0): a name is paired with the image's function only when it is unique on both
    sides; the others (a static name in two files) keep the frame read from the code."""
    lto = sorted(build.glob(f"{image}.ltrans*.ltrans.su"))
    files = lto or sorted((build / "mcahrs_core").rglob("*.su"))
    entries: dict[str, list[tuple[int, str]]] = defaultdict(list)
    for su in files:
        for line in su.read_text().splitlines():
            parts = line.split("\t")
            if len(parts) == 3:
                entries[parts[0].rsplit(":", 1)[-1]].append((int(parts[1]), parts[2]))
    if not lto:
        return {f: e[-1] for f, e in entries.items()}
    by_key: dict[str, list[str]] = defaultdict(list)
    for f in funcs:
        by_key[re.sub(r"(\.lto_priv)?\.\d+$", "", f).removesuffix(".lto_priv")].append(f)
    return {by_key[k][0]: e[0] for k, e in entries.items() if len(e) == 1 and len(by_key.get(k, ())) == 1}


def disassemble(elf: Path) -> dict[str, list[tuple[str, str]]]:
    """function -> [(mnemonic, operands)] of the linked image."""
    txt = subprocess.run(
        ["arm-none-eabi-objdump", "-d", "--no-show-raw-insn", str(elf)],
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    funcs: dict[str, list[tuple[str, str]]] = {}
    cur = None
    for line in txt.splitlines():
        m = re.match(r"^[0-9a-f]+ <([^>]+)>:$", line)
        if m:
            cur = m.group(1)
            funcs[cur] = []
            continue
        m = re.match(r"^\s+[0-9a-f]+:\s+(\S+)\s*(.*)$", line)
        if m and cur is not None:
            funcs[cur].append((m.group(1), m.group(2)))
    return funcs


def _reg_count(regs: str) -> tuple[int, int]:
    """(core registers, bytes of FP registers) in a {...} list, ranges expanded."""
    core, fp = 0, 0
    for r in regs.strip("{} ").split(","):
        r = r.strip()
        m = re.match(r"([sd])(\d+)(?:-[sd](\d+))?$", r)
        if m:
            n = int(m.group(3) or m.group(2)) - int(m.group(2)) + 1
            fp += n * (8 if m.group(1) == "d" else 4)
        elif r:
            core += 1
    return core, fp


def frame_from_code(insns: list[tuple[str, str]]) -> int:
    """Stack a function allocates: every push/stmdb, vpush/vstmdb, sub sp and str ..! in it,
    summed (an upper bound: a shrink-wrapped function saves registers after its first
    branches, and a function with two save sites is counted twice)."""
    total = 0
    for mn, ops in insns:
        base = mn.split(".")[0]
        if base in ("push", "stmdb") and (base == "push" or ops.startswith("sp!")):
            core, fp = _reg_count(ops[ops.index("{") :])
            total += 4 * core + fp
        elif base in ("vpush", "vstmdb") and (base == "vpush" or ops.startswith("sp!")):
            total += _reg_count(ops[ops.index("{") :])[1]
        elif base in ("sub", "subw") and re.match(r"sp, (sp, )?#(\d+)", ops):
            total += int(re.match(r"sp, (sp, )?#(\d+)", ops).group(2))
        elif base == "str" and re.search(r"\[sp, #-(\d+)\]!", ops):
            total += int(re.search(r"\[sp, #-(\d+)\]!", ops).group(1))
    return total


_BRANCH = re.compile(r"^b(l|lx)?(eq|ne|cs|cc|hs|lo|mi|pl|vs|vc|hi|ls|ge|lt|gt|le|al)?$")


def call_graph(funcs: dict[str, list[tuple[str, str]]]) -> tuple[dict[str, set[str]], set[str]]:
    """Edges f -> g for bl/blx to g and for branches to another function's start (tail calls);
    the set of functions with an indirect call (blx/bx through a register other than lr)."""
    edges: dict[str, set[str]] = defaultdict(set)
    indirect = set()
    for f, insns in funcs.items():
        for mn, ops in insns:
            base = mn.split(".")[0]
            if not _BRANCH.match(base) and base != "bx":
                continue
            m = re.search(r"<([^>+]+)(\+0x[0-9a-f]+)?>", ops)
            if m:
                if m.group(1) != f and not m.group(2):
                    edges[f].add(m.group(1))
            elif re.match(r"r\d+|ip", ops.strip()) and base in ("blx", "bx"):
                indirect.add(f)
    return edges, indirect


def worst_stack(fn: str, frames: dict[str, int], edges: dict[str, set[str]]) -> tuple[int, list[str], bool]:
    """Deepest frame chain from fn (tail calls counted as calls: an upper bound). Iterative,
    memoised; a cycle (recursion) is reported and cut."""
    memo: dict[str, tuple[int, list[str]]] = {}
    cyclic = False
    stack = [(fn, 0)]
    on_path: set[str] = set()
    while stack:
        f, state = stack.pop()
        if state == 0:
            if f in memo:
                continue
            on_path.add(f)
            stack.append((f, 1))
            for g in edges.get(f, ()):
                if g in on_path:
                    cyclic = True
                elif g not in memo:
                    stack.append((g, 0))
        else:
            best, path = 0, []
            for g in edges.get(f, ()):
                if g in memo and memo[g][0] > best:
                    best, path = memo[g]
            memo[f] = (frames.get(f, 0) + best, [f] + path)
            on_path.discard(f)
    return memo[fn][0], memo[fn][1], cyclic


# ----------------------------------------------------------------------------- main


def public_functions(archive: Path) -> list[str]:
    out = subprocess.run(
        ["arm-none-eabi-nm", "-g", "--defined-only", str(archive)], check=True, capture_output=True, text=True
    ).stdout
    return sorted({ln.split()[-1] for ln in out.splitlines() if re.match(r"^[0-9a-f]+ T ", ln)})


def ins_applied_updates(costs: gv.Costs, out: Path) -> np.ndarray:
    """Instructions of the mca_ins_gps calls after which n_gps_upd of the next INS_OUTPUT grew (an
    update applied, not a fix skipped before alignment or rejected)."""
    recs = gv.read_records(out)
    gps = costs.calls[costs.calls["id"] == gv.EP["INS_GPS"]]
    instr = {int(c): int(a) for c, a in zip(gps["c"], gps["a"], strict=True)}
    dt = gv.out_dtype(gv.OP["INS_OUTPUT"])
    applied, n_upd, pending = [], 0, None
    for i, (op, payload) in enumerate(recs):
        if op == gv.OP["INS_GPS"]:
            pending = i
        elif op == gv.OP["INS_OUTPUT"]:
            n = int(np.frombuffer(payload, dt)[0]["n_gps_upd"])
            if pending is not None and n > n_upd and pending in instr:
                applied.append(instr[pending])
            n_upd, pending = n, None
        elif op == gv.OP["INS_INIT_PRESET"]:
            n_upd, pending = 0, None
    return np.array(applied, np.float64)


def ins_vs_nav(args, build: Path, meta: dict, samples: dict, painted: dict, frames: dict, edges: dict,
               applied: np.ndarray) -> None:  # fmt: skip
    """Section 4b: the INS and the CS + gravity navigation filter side by side."""
    print(
        "\n4b. The loosely-coupled INS (mca_ins.h, 15-state error-state EKF) beside the CS + gravity "
        "navigation filter (mca_nav.h), same build and method (instructions over every vector file)"
    )
    if "ins_imu" not in samples or "nav_imu" not in samples:
        print("  (the vectors lack INS or navigation calls)")
        return

    def own_flash(img: str, obj: str) -> tuple[int, int]:
        """(bytes of the core object `obj`, flash of the whole core-alone image) of mca_core_<img>.elf."""
        mp = build / f"mca_core_{img}.elf.map"
        if not mp.exists():
            return 0, 0
        g = map_groups(mp)
        c = g.get(f"core {obj}", {})
        return (
            sum(c.get(k, 0) for k in ("text", "rodata", "data")),
            sum(x["text"] + x["rodata"] + x["data"] for x in g.values()),
        )

    def dist(a: np.ndarray) -> str:
        return f"{a.mean():7.0f} {np.percentile(a, 99):7.0f} {a.max():7.0f} {a.size:6d}"

    ins_obj, ins_img = own_flash("ins", "mca_ins.c")
    nav_obj, nav_img = own_flash("nav", "mca_nav.c")
    st_ins, st_nav = meta.get("sizeof_ins", 0), meta.get("sizeof_nav", 0)

    def row(label: str, ins: str, nav: str) -> None:
        print(f"  {label:40s} {ins:>30s}   {nav:>30s}")

    row("", "INS (mca_ins)", "CS + gravity nav (mca_nav)")
    row("state RAM, sizeof (B)", f"mca_ins_t {st_ins}", f"mca_nav_t {st_nav}")
    row("flash of the filter file (B)", f"mca_ins.c {ins_obj}", f"mca_nav.c {nav_obj}")
    row("flash, core alone with its header as roots", f"mca_ins.h {ins_img}", f"mca_nav.h {nav_img}")
    for step in ("imu", "gps"):
        cells = []
        for f in ("ins", "nav"):
            fn = f"mca_{f}_{step}"
            depth = worst_stack(fn, frames, edges)[0] if fn in frames else 0
            cells.append(f"{fn} {depth} / {painted.get(f'{f}_{step}', 0)}")
        row(f"worst stack {step.upper()} step, static / painted (B)", *cells)
    head = "mean     p99     max  calls"
    row("instructions per call", head, head)
    row("  IMU step", dist(samples["ins_imu"]), dist(samples["nav_imu"]))
    row("  GNSS step (every call)", dist(samples["ins_gps"]), dist(samples["nav_gps"]))
    if applied.size:
        row("  GNSS step (INS: updates applied)", dist(applied), "")
    hz_i, hz_g, clk = args.imu_hz, args.ins_gps_hz, args.mhz * 1e6
    cells = []
    for f in ("ins", "nav"):
        imu, gps = samples[f"{f}_imu"], samples[f"{f}_gps"]
        load = (hz_i * imu.mean() + hz_g * gps.mean()) * args.cpi / clk
        worst_us = (imu.max() + gps.max()) * args.cpi / args.mhz
        cells.append(f"{100 * load:5.2f} %, worst {worst_us:6.0f} us")
    row(f"CPU {args.mhz:g} MHz, {hz_i:g} Hz IMU + {hz_g:g} Hz GNSS", *cells)
    print(
        f"  (CPU: mean load at {args.cpi:g} cycles per instruction; worst = the longest IMU step and the "
        f"longest GNSS step back to back, against the {1e6 / hz_i:.0f} us IMU period. INS instructions "
        "from tests/vectors/ins_fixedwing_turns (400 Hz IMU, 5 Hz GNSS, cov_dt_s of the preset); nav "
        "from the nav_* files (10 Hz GPS; per-call costs do not depend on the rate))"
    )


OPT_OF_BUILD = {"MinSizeRel": "-Os", "Release": "-O2"}  # c_core/firmware/CMakeLists.txt
FW_CMAKE = Path(__file__).resolve().parent.parent / "c_core" / "firmware" / "CMakeLists.txt"


def opt_flags(build_type: str) -> str:
    """The optimisation flags of a firmware build type as c_core/firmware/CMakeLists.txt sets them
    (MinSizeRel: -Os and the passes it leaves out, MCA_FW_SIZE_FLAGS)."""
    text = FW_CMAKE.read_text()
    m = re.search(r'^set\(MCA_FW_SIZE_FLAGS "([^"]*)"\)', text, re.M)
    extra = f" {m.group(1)}" if build_type == "MinSizeRel" and m else ""
    return OPT_OF_BUILD[build_type] + extra


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cpi", type=float, default=1.25, help="cycles per instruction assumed (default 1.25)")
    ap.add_argument("--mhz", type=float, default=168.0)
    ap.add_argument("--imu-hz", type=float, default=400.0)
    ap.add_argument("--gps-hz", type=float, default=10.0)
    ap.add_argument(
        "--ins-gps-hz", type=float, default=5.0, help="GNSS rate of the INS vs nav comparison (default 5)"
    )
    ap.add_argument(
        "--build-type",
        choices=sorted(OPT_OF_BUILD),
        default="MinSizeRel",
        help="MinSizeRel: -Os, the firmware (default); Release: -O2, the speed variant",
    )
    args = ap.parse_args(argv)

    build = gv.FW_BUILD if args.build_type == "MinSizeRel" else gv.REPO / "build" / f"fw-{args.build_type}"
    elf = gv.build_firmware(build, args.build_type)
    gcc = subprocess.run(["arm-none-eabi-gcc", "-dumpversion"], capture_output=True, text=True).stdout.strip()
    print(
        f"MCAHRS Cortex-M4F report: arm-none-eabi-gcc {gcc}, {opt_flags(args.build_type)} "
        f"-mcpu=cortex-m4 -mfpu=fpv4-sp-d16 -mfloat-abi=hard, newlib-nano, {build.relative_to(gv.REPO)}"
    )

    # ---- run the vectors (costs) and the comparisons
    runs = {}
    ins_applied: list[np.ndarray] = []  # instructions of the mca_ins_gps calls that applied an update
    with tempfile.TemporaryDirectory() as tmp:
        host = gv.build_host_replay()
        for vec in gv.vector_files():
            out, cost = Path(tmp) / f"{vec.stem}.mcao", Path(tmp) / f"{vec.stem}.cost"
            r = gv.run_qemu(elf, vec, out, cost)
            if r.returncode != 0:
                print(f"QEMU failed on {vec.name}: exit {r.returncode} {r.stdout}{r.stderr}")
                return 1
            href = Path(tmp) / f"{vec.stem}.host.mcao"
            gv.run_host(host, vec, href)
            hp, qp = Path(tmp) / f"{vec.stem}.hp", Path(tmp) / f"{vec.stem}.qp"
            gv.run_host(host.with_name("replay_pinned"), vec, hp)
            gv.run_qemu(elf.with_name("fw_pinned.elf"), vec, qp)
            if not any(vec.stem in names for names in ROBUST_VECTORS.values()):
                ins_applied.append(ins_applied_updates(gv.read_costs(cost), out))
            runs[vec.stem] = (
                gv.read_costs(cost),
                gv.compare_outputs(href, out),
                hp.read_bytes() == qp.read_bytes(),
            )
    meta = next(iter(runs.values()))[0].meta

    # ---- 1. flash and RAM
    print("\n1. Flash and RAM (bytes; flash = text + rodata + data initialisers)")
    nav_elf = build / "mca_core_nav.elf"
    flash_nav = None
    if nav_elf.exists():
        flash_nav = print_groups(
            "core alone, roots = the functions of mca_nav.h (what a flight controller calls):",
            map_groups(Path(str(nav_elf) + ".map")),
        )
        print(
            f"    core flash {flash_nav} B = {flash_nav / KIB:.1f} KiB   "
            f"goal <= 24 KiB: {ok(flash_nav, GOAL_FLASH)}"
        )
        nolto = build / "mca_core_nav_nolto.elf.map"
        if nolto.exists():
            g = map_groups(nolto)
            n = sum(c["text"] + c["rodata"] + c["data"] for c in g.values())
            print(
                f"    (linked with LTO: a file's figure holds what the link inlined into its functions. "
                f"The same objects linked without LTO, their ordinary code: {n} B = {n / KIB:.1f} KiB, "
                f"{n - flash_nav:+d} B)"
            )
        mem = map_groups(Path(str(nav_elf) + ".map"), members=True)
        libs = sorted(((c["text"] + c["rodata"], g) for g, c in mem.items() if ":" in g), reverse=True)
        print("    largest library members: " + ", ".join(f"{g} {n}" for n, g in libs[:8]))
    g_all = map_groups(Path(str(build / "mca_core_only.elf") + ".map"))
    flash_all = sum(c["text"] + c["rodata"] + c["data"] for c in g_all.values())
    print(
        f"  core alone, roots = every public function (adds the batch replay etc.): "
        f"flash {flash_all} B = {flash_all / KIB:.1f} KiB"
    )
    dbl = sum(c["text"] for g, c in g_all.items() if g == "libgcc")
    print(f"    of which libgcc {dbl} B (64-bit conversion and soft-float helpers: see the end)")
    prof = g_all.get("core mca_profile.c", {})
    if prof:
        n = sum(prof.get(k, 0) for k in ("text", "rodata", "data"))
        print(
            f"    of which mca_profile.c {n} B: mca_nav_config_robust_profile, the robust profiles as one "
            "set-up call (mca_profile.h), linked only by an autopilot that calls it"
        )
    size = subprocess.run(
        ["arm-none-eabi-size", str(elf)], capture_output=True, text=True
    ).stdout.splitlines()[1]
    t, d, b = (int(x) for x in size.split()[:3])
    print(
        f"  whole replay image fw.elf: text {t}  data {d}  bss {b} (bss: {meta.get('stack_bytes', 0)} stack, "
        f"2 x 4 KiB file buffers, the filter states)"
    )
    st_nav, st_cs = meta.get("sizeof_nav", 0), meta.get("sizeof_cs3", 0)
    print(
        f"  state RAM: sizeof(mca_nav_t) = {st_nav} B ({st_nav / KIB:.2f} KiB)   goal <= 4 KiB: "
        f"{ok(st_nav, GOAL_STATE)}   [sizeof(mca_cs3_t) = {st_cs} B, inside it]"
    )
    core_rw = sum(
        c["data"] + c["bss"]
        for g, c in (map_groups(Path(str(nav_elf) + ".map")) if nav_elf.exists() else g_all).items()
    )
    print(f"  static RAM of the core + libraries: {core_rw} B (newlib's errno/impure data pulled by libm)")

    # ---- 2. stack
    print(
        f"\n2. Stack per public function (bytes): static worst case = .su frames + call graph of "
        f"{build.name}/mca_core_only.elf; fw.elf = the same for the replay image's own code (its link "
        "inlines differently); painted = high-water measured in QEMU over all vectors"
    )
    funcs = disassemble(build / "mca_core_only.elf")
    su = su_frames(build, "mca_core_only", funcs)
    frames = {f: su[f][0] if f in su else frame_from_code(ins) for f, ins in funcs.items()}
    mism = [f for f in su if f in funcs and frame_from_code(funcs[f]) != su[f][0]]
    dyn = [f for f, (_, q) in su.items() if q != "static"]
    edges, indirect = call_graph(funcs)
    # The replay image fw.elf, whose stack QEMU paints: linked with LTO, its code for an entry
    # point is not the core-alone image's (the inliner sees other callers), so the painted
    # high-water is checked against the static worst case of fw.elf's own code.
    funcs_fw = disassemble(elf)
    su_fw = su_frames(build, "fw", funcs_fw)
    frames_fw = {f: su_fw[f][0] if f in su_fw else frame_from_code(ins) for f, ins in funcs_fw.items()}
    edges_fw, _ = call_graph(funcs_fw)
    painted = defaultdict(int)
    for costs, _, _ in runs.values():
        for ep, stk in zip(costs.calls["id"], costs.calls["b"], strict=True):
            painted[gv.EP_NAME.get(int(ep), "?")] = max(painted[gv.EP_NAME.get(int(ep), "?")], int(stk))
    pub = public_functions(build / "mcahrs_core" / "libmcahrs_core.a")
    pub.sort(key=lambda f: (not f.startswith("mca_nav_"), f))
    print(
        f"  {'function':28s} {'static':>6s} {'fw.elf':>6s} {'painted':>7s}  goal <= 1 KiB   "
        "deepest chain (function frame, ...)"
    )
    worst_static = 0
    for f in pub:
        if f not in funcs:
            continue
        depth, path, cyc = worst_stack(f, frames, edges)
        worst_static = max(worst_static, depth)
        p = painted.get(f[len("mca_") :], None)
        in_fw = worst_stack(f, frames_fw, edges_fw)[0] if p is not None and f in funcs_fw else None
        worst_static = max(worst_static, in_fw or 0)
        flag = " RECURSION" if cyc else ""
        flag += " INDIRECT CALL" if set(path) & indirect else ""
        chain = " > ".join(f"{x.replace('mca_', '')} {frames.get(x, 0)}" for x in path[:5])
        chain += " > ..." if len(path) > 5 else ""
        goal = ok(max(depth, in_fw or 0), GOAL_STACK)
        fw_txt = "" if in_fw is None else in_fw
        print(f"  {f:28s} {depth:6d} {fw_txt:>6} {'' if p is None else p:>7}  {goal:13s}  {chain}{flag}")
    painted_ok = all(
        painted[e] <= worst_stack("mca_" + e, frames_fw, edges_fw)[0]
        for e in painted
        if "mca_" + e in funcs_fw
    )
    mism_txt = ", ".join(f"{f} {su[f][0]}/{frame_from_code(funcs[f])}" for f in mism[:4])
    print(
        f"  cross-checks: .su frame vs frame read from the code (.su/code) differ for {len(mism)} of "
        f"{len(su)} core functions{': ' + mism_txt if mism else ''}; non-static .su entries: "
        f"{dyn or 'none'}; indirect calls: "
        f"{sorted(indirect) or 'none'}. Painted <= static (fw.elf) for every measured entry point: "
        f"{painted_ok}"
    )

    # ---- 3. instructions
    print(
        f"\n3. Instructions per call (QEMU -icount shift=0, SysTick vernier, exact; the count includes the "
        f"call and its argument set-up), over {len(runs)} vector files"
    )
    per_ep: dict[str, list[np.ndarray]] = defaultdict(list)
    profile_of = {v: label for label, names in ROBUST_VECTORS.items() for v in names}
    robust_ep: dict[str, dict[str, list[np.ndarray]]] = defaultdict(lambda: defaultdict(list))
    for name, (costs, _, _) in runs.items():
        for ep in np.unique(costs.calls["id"]):
            calls = costs.calls["a"][costs.calls["id"] == ep]
            group = robust_ep[profile_of[name]] if name in profile_of else per_ep
            group[gv.EP_NAME.get(int(ep), str(ep))].append(calls)
    stats = {}
    samples: dict[str, np.ndarray] = {}
    print(f"  {'entry point':16s} {'calls':>6s} {'mean':>8s} {'p99':>8s} {'max':>8s} {'min':>7s}  goal")
    for ep in sorted(per_ep, key=lambda e: gv.EP[e.upper()]):
        a = np.concatenate(per_ep[ep]).astype(np.float64)
        stats[ep] = (a.mean(), a.max())
        samples[ep] = a
        goal = GOAL_INSTR.get(ep)
        gtxt = f"<= {goal}: mean {ok(a.mean(), goal)}, max {ok(a.max(), goal)}" if goal else ""
        print(
            f"  mca_{ep:12s} {a.size:6d} {a.mean():8.0f} {np.percentile(a, 99):8.0f} {a.max():8.0f} "
            f"{a.min():7.0f}  {gtxt}"
        )
    robust_stats = {}
    for label, eps in robust_ep.items():
        names = ", ".join(ROBUST_VECTORS[label])
        print(f"  {label} ({names}; the goals above are the base filter's):")
        for ep in ("nav_imu", "nav_gps", "ins_imu", "ins_gps"):
            if ep in eps:
                a = np.concatenate(eps[ep]).astype(np.float64)
                if label == ROWS_PROFILE:
                    robust_stats[ep] = (a.mean(), a.max())
                print(
                    f"  mca_{ep:12s} {a.size:6d} {a.mean():8.0f} {np.percentile(a, 99):8.0f} {a.max():8.0f} "
                    f"{a.min():7.0f}"
                )

    # ---- 4. CPU share
    cyc_us = args.mhz
    print(
        f"\n4. CPU at {args.mhz:g} MHz, assuming {args.cpi:g} cycles per instruction on the M4F (flash wait "
        "states behind the ART cache, 2-cycle loads, 14-cycle VDIV/VSQRT; QEMU counts instructions, "
        "not cycles)"
    )
    if "nav_imu" in stats and "nav_gps" in stats:
        imu, gps = stats["nav_imu"], stats["nav_gps"]
        out = stats.get("nav_output", (0.0, 0.0))
        mean = (args.imu_hz * imu[0] + args.gps_hz * gps[0]) * args.cpi / (args.mhz * 1e6)
        with_out = mean + args.imu_hz * out[0] * args.cpi / (args.mhz * 1e6)
        print(
            f"  {args.imu_hz:g} Hz IMU step + {args.gps_hz:g} Hz GPS step: mean load {100 * mean:.2f} % "
            f"({100 * with_out:.2f} % with mca_nav_output after every IMU step)"
        )
        print(
            f"  longest IMU step {imu[1] * args.cpi / cyc_us:.1f} us of its {1e6 / args.imu_hz:.0f} us "
            "period; "
            f"longest GPS step {gps[1] * args.cpi / cyc_us:.1f} us"
        )
        print(
            f"  at 1 kHz IMU (DESIGN.md 7 upper rate): mean load "
            f"{100 * (1000 * imu[0] + args.gps_hz * gps[0]) * args.cpi / (args.mhz * 1e6):.2f} %"
        )
        if "nav_imu" in robust_stats and "nav_gps" in robust_stats:
            rimu, rgps = robust_stats["nav_imu"], robust_stats["nav_gps"]
            rmean = (args.imu_hz * rimu[0] + args.gps_hz * rgps[0]) * args.cpi / (args.mhz * 1e6)
            print(
                f"  the fuzzy-rows profile: mean load {100 * rmean:.2f} %, longest GPS step "
                f"{rgps[1] * args.cpi / cyc_us:.1f} us"
            )
    else:
        print("  (no navigation calls in the vectors)")

    # ---- 4b. the INS beside the navigation filter
    ins_vs_nav(args, build, meta, samples, painted, frames_fw, edges_fw, np.concatenate(ins_applied))

    # ---- 5. host vs QEMU
    print(
        f"\n5. Host (x86-64, glibc) vs QEMU (M4F, newlib) on the same vectors: integers exactly, floats to "
        f"{gv.RTOL_LIBM:g} of each component's scale; pinned libm must be bit-identical"
    )
    print(
        f"  {'vector':20s} {'records':>7s} {'floats':>7s} {'bit-identical':>13s} {'worst/scale':>11s}  "
        f"{'result':6s} pinned libm"
    )
    for name, (_, cmp, pinned_same) in runs.items():
        same = 100 * cmp.floats_identical / max(cmp.floats, 1)
        print(
            f"  {name:20s} {cmp.records:7d} {cmp.floats:7d} {same:12.1f}% {cmp.worst:11.1e}  "
            f"{'ok' if cmp.ok() else 'FAIL':6s} {'identical' if pinned_same else 'DIFFERENT'}"
        )
    helpers = defaultdict(set)
    for f, insns in funcs.items():
        if f.startswith("mca_") or f in su:
            for mn, ops in insns:
                m = re.search(r"<(__aeabi_\w+)>", ops)
                if m and mn.split(".")[0] in ("bl", "b", "blx"):
                    helpers[m.group(1)].add(f)
    if helpers:
        print(
            "\nlibgcc helpers the core calls (the M4F FPU is single precision, with no 64-bit conversions):"
        )
        for h in sorted(helpers):
            print(f"  {h:16s} from {', '.join(sorted(helpers[h]))}")
        print(
            "  float -> 64-bit integer (__aeabi_f2lz/f2ulz) is done in libgcc with double soft-float (f2d,"
            " dmul, dsub, d2uiz); 64-bit integer -> float (__aeabi_l2f/ul2f) shares an object with soft-float"
            " fadd. Converting 32-bit values instead keeps both in the FPU (one vcvt)."
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
