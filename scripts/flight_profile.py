#!/usr/bin/env python3
"""Instructions per function of the flight firmware under QEMU (a sampling-free profile).

Usage: python3 scripts/flight_profile.py ELF [TOP]

Runs ELF (the firmware `orbfix budget` built last, e.g.
target/thumbv7em-none-eabihf/release/orbfix-firmware, which holds that run's test vectors)
in qemu-system-arm (mps2-an500) with `-d in_asm,exec,nochain`: QEMU logs each translated
block once with its instructions and each block it executes, so the instructions of every
block times its executions is an exact count per address. Prints the TOP (default 25)
functions by instructions, from the ELF's symbols (llvm-nm). Needs qemu-system-arm and
llvm-nm; the log goes through a pipe, not to disk.
"""
import bisect
import collections
import os
import re
import subprocess
import sys
import tempfile


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    elf = sys.argv[1]
    top = int(sys.argv[2]) if len(sys.argv) > 2 else 25
    if not os.path.isfile(elf):
        sys.exit(f"flight_profile: no firmware at {elf}: run `orbfix budget` first")
    size, runs = {}, collections.Counter()
    pc_re = re.compile(r"^0x([0-9a-f]{8}):")
    with tempfile.TemporaryDirectory() as tmp:
        fifo = os.path.join(tmp, "log")
        os.mkfifo(fifo)
        qemu = subprocess.Popen(
            ["qemu-system-arm", "-cpu", "cortex-m7", "-machine", "mps2-an500", "-nographic",
             "-semihosting-config", "enable=on,target=native", "-icount", "shift=0",
             "-kernel", elf, "-d", "in_asm,exec,nochain", "-D", fifo],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        cur = None
        with open(fifo) as log:
            for line in log:
                if line.startswith("Trace"):
                    i = line.index("[")
                    runs[int(line[i + 10:i + 18], 16)] += 1
                elif line.startswith("IN:"):
                    cur = None
                else:
                    m = pc_re.match(line)
                    if m:
                        if cur is None:
                            cur = int(m.group(1), 16)
                            size[cur] = 0
                        size[cur] += 1
        qemu.wait()
    nm = subprocess.run(["llvm-nm", "-S", "-C", elf], capture_output=True, text=True, check=True)
    syms = []
    for l in nm.stdout.splitlines():
        p = l.split(None, 3)
        if len(p) == 4 and p[2] in "tT":
            syms.append((int(p[0], 16) & ~1, int(p[1], 16), p[3]))
    syms.sort()
    starts = [s[0] for s in syms]
    per = collections.Counter()
    for pc, n in runs.items():
        i = bisect.bisect_right(starts, pc) - 1
        name = syms[i][2] if i >= 0 and pc < syms[i][0] + syms[i][1] else "?"
        per[re.sub(r"::h[0-9a-f]{16}$", "", name)] += n * size.get(pc, 0)
    total = sum(per.values())
    print(f"{total:>13,} instructions in all (QEMU exit status {qemu.returncode})")
    for name, n in per.most_common(top):
        print(f"{n:>13,} {100 * n / max(total, 1):5.1f} %  {name}")


if __name__ == "__main__":
    main()
