#!/usr/bin/env python3
"""Fails when code of orbfix needs an x86_64 stack probe (docs/toolchain.md).

A stack probe is the code LLVM puts before a stack frame of 4096 bytes or more: one
`sub $0x1000,%rsp` and a store per 4 KiB page, unrolled up to 8 pages, and from 32 KiB on
a loop that steps `%rsp` down to a limit kept in `%r11`. The release build of 6eea12b
miscompiled `CnnMatcher::score` at such a loop (shrink-wrapping placed it after code that
held a live value in `%r11`). Rules checked:

1. core (`orbfix::`, crate `orbfix`): no probe at all, i.e. every frame under 4 KiB, in the
   core's release library (every core function) and in the host binary (where generic core
   code is instantiated). No allow-list.
2. host binary: no probe *loop* in a function of orbfix (`orbfix::`/`orbfix_host::`) or in
   a function of another crate called directly from one (generic code instantiated for ours,
   e.g. `Vec::from_iter` of our types).
3. host binary: unrolled probes (frames of 4 to 32 KiB, no scratch register) in host
   functions only where scripts/stack-probe-allow.txt allows them, each entry with its reason.

Usage: python3 scripts/stack-probe-check.py [--binary FILE] [--core-rlib FILE]
Defaults: $CARGO_TARGET_DIR/release/orbfix and the newest release liborbfix-*.rlib.
"""
import argparse
import glob
import os
import re
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
ALLOW = os.path.join(HERE, "stack-probe-allow.txt")

FUNC = re.compile(r"^([0-9a-f]+) <(.*)>:$")
PAGE = re.compile(r"\bsub\s+\$0x1000,%rsp$")
LOOP_LIMIT = re.compile(r"\bsub\s+\$(0x[0-9a-f]+),%r11$")
REST = re.compile(r"\bsub\s+\$(0x[0-9a-f]+),%rsp$")
CALL = re.compile(r"\bcall\s+([0-9a-f]+) <")


def scan(path):
    """{address: (name, frame_bytes, is_loop, callees)} for every function with a probe,
    plus the callees of every function (to attribute generic code)."""
    out = subprocess.run(
        ["objdump", "-d", "--no-show-raw-insn", "-C", path],
        check=True, capture_output=True, text=True,
    ).stdout
    funcs = {}
    cur = None
    for line in out.splitlines():
        m = FUNC.match(line)
        if m:
            cur = {"addr": int(m.group(1), 16), "name": m.group(2), "pages": 0, "loop": 0,
                   "rest": 0, "calls": set()}
            # Object files (rlib) restart addresses at 0 per section: key by name there.
            funcs[(m.group(1), m.group(2))] = cur
            continue
        if cur is None:
            continue
        line = line.rstrip()
        if PAGE.search(line):
            cur["pages"] += 1
        elif (m := LOOP_LIMIT.search(line)) is not None:
            cur["loop"] = int(m.group(1), 16)
        elif cur["pages"] and not cur["rest"] and (m := REST.search(line)) is not None:
            cur["rest"] = int(m.group(1), 16)
        elif (m := CALL.search(line)) is not None:
            cur["calls"].add(int(m.group(1), 16))
    for f in funcs.values():
        f["frame"] = (f["loop"] or f["pages"] * 4096) + f["rest"]
    return funcs


CORE_MODULES = set()  # first path segments of the core's functions, read from its rlib


def is_core(name):
    """A core function, or generic code instantiated for a core type (the binary is also
    named `orbfix`: its `orbfix::cmd`, `orbfix::main` are host code)."""
    # `<Type as Trait>::f` is the type's code: a host type implementing a core trait is host.
    own = re.sub(r" as [^<>]*(<[^<>]*>)*[^<>]*>", ">", name)
    return any(f"orbfix::{m}::" in own for m in CORE_MODULES)


def is_ours(name):
    return "orbfix::" in name or "orbfix_host::" in name


def load_allow():
    pats = []
    if os.path.exists(ALLOW):
        for line in open(ALLOW, encoding="utf-8"):
            line = line.split("#", 1)[0].strip()
            if line:
                pats.append(line)
    return pats


def main():
    target = os.environ.get("CARGO_TARGET_DIR", os.path.join(ROOT, "target"))
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--binary", default=os.path.join(target, "release", "orbfix"))
    ap.add_argument("--core-rlib", default=None)
    a = ap.parse_args()
    rlib = a.core_rlib
    if rlib is None:
        cands = sorted(glob.glob(os.path.join(target, "release", "deps", "liborbfix-*.rlib")),
                       key=os.path.getmtime)
        rlib = cands[-1] if cands else None
    for p in [a.binary, rlib]:
        if p is None or not os.path.exists(p):
            sys.exit(f"stack-probe-check: {p or 'the core rlib'} is missing; build it first "
                     "with 'cargo build --release -p orbfix-host'")
    allow = load_allow()
    failures, allowed = [], []

    core = scan(rlib)
    for f in core.values():
        for m in re.finditer(r"orbfix::([a-z_0-9]+)::", f["name"]):
            CORE_MODULES.add(m.group(1))
    core_probed = [f for f in core.values() if f["pages"] and is_core(f["name"])]
    for f in core_probed:
        failures.append(f"core rlib: {f['name']} ({f['frame']} byte frame)")

    host = scan(a.binary)
    by_addr = {f["addr"]: f for f in host.values()}
    called_by_ours = set()
    for f in host.values():
        if is_ours(f["name"]):
            called_by_ours |= f["calls"]
    n_other = 0
    for f in host.values():
        if not f["pages"]:
            continue
        name = f["name"]
        where = f"{os.path.basename(a.binary)}: {name} ({f['frame']} byte frame"
        where += ", probe loop)" if f["loop"] else ")"
        if is_core(name):
            failures.append(where)
        elif f["loop"] and (is_ours(name) or f["addr"] in called_by_ours):
            failures.append(where)
        elif is_ours(name):
            if any(p in name for p in allow):
                allowed.append(where)
            else:
                failures.append(where)
        else:
            n_other += 1

    for w in allowed:
        print(f"stack-probe-check: allowed (scripts/stack-probe-allow.txt): {w}")
    for w in failures:
        print(f"stack-probe-check: STACK PROBE: {w}", file=sys.stderr)
    print(f"stack-probe-check: core rlib: {len(core)} functions scanned, {len(core_probed)} "
          f"with a probe; host binary: {len(host)} functions scanned, {len(allowed)} allowed "
          f"unrolled probes in host code, {n_other} probes in other crates' code not called "
          f"from ours (not checked); {len(failures)} failures")
    if failures:
        print("stack-probe-check: move the large buffers of the functions above off the stack "
              "(caller-provided or static, with a sizing function; docs/toolchain.md)",
              file=sys.stderr)
        sys.exit(1)


if __name__ == "__main__":
    main()
