#!/usr/bin/env python3
"""The heading-search tables of docs/traverse.md from the drives' JSON.

Usage: python3 scripts/heading_table.py DIR
DIR holds what scripts/traverse-results.sh writes: {same,cross}-sun-s{2,3,4}/traverse.json
(drives with --compare-heading-sigma-deg) and, if present, step1-s2 and step0.5-s2. Prints
one markdown row per drive, the pooled rows, then the step comparison. "Within 1 m" counts a
stop without a fix (no data) as a miss; medians and means are over the stops with a fix.
"""
import json
import os
import statistics as st
import sys

HEADER = ("| condition | seed | headings tried | within 1 m: known heading | sigma 2 deg, no search "
          "| sigma 2 deg, search | median fix error m: known / no search / search "
          "| mean abs heading error deg: given / after search | host ms: one fix / search |\n"
          "|---|---:|---:|---:|---:|---:|---|---|---|")


def stats(stops):
    c = [s["compare"] for s in stops if s.get("compare")]
    if not c:
        sys.exit("heading_table: no stop has a heading comparison (run with --compare-heading-sigma-deg)")
    n = len(c)

    def within(k):
        return sum(1 for x in c if x[k] is not None and x[k] <= 1.0) / n

    def med(k):
        return st.median([x[k] for x in c if x[k] is not None])

    def mean_abs(k):
        return st.mean([abs(x[k]) for x in c if x[k] is not None])

    return (max(x["search_tried"] for x in c), within("known_error_m"), within("noisy_error_m"),
            within("search_error_m"), med("known_error_m"), med("noisy_error_m"),
            med("search_error_m"), mean_abs("noisy_heading_error_deg"),
            mean_abs("search_heading_error_deg"), st.mean(x["known_ms"] for x in c),
            st.mean(x["search_ms"] for x in c))


def row(name, seed, s):
    return (f"| {name} | {seed} | {s[0]} | {s[1]:.3f} | {s[2]:.3f} | {s[3]:.3f} | "
            f"{s[4]:.3f} / {s[5]:.3f} / {s[6]:.3f} | {s[7]:.2f} / {s[8]:.2f} | "
            f"{s[9]:.0f} / {s[10]:.0f} |")


def load(d, name):
    path = os.path.join(d, name, "traverse.json")
    try:
        with open(path) as f:
            return json.load(f)["stops"]
    except (OSError, ValueError, KeyError) as e:
        sys.exit(f"heading_table: cannot read {path}: {e}")


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    d = sys.argv[1]
    pooled = {}
    print(HEADER)
    for cond in ("same-sun", "cross-sun"):
        for seed in (2, 3, 4):
            stops = load(d, f"{cond}-s{seed}")
            pooled.setdefault(cond, []).extend(stops)
            print(row(cond, seed, stats(stops)))
    for cond in ("same-sun", "cross-sun"):
        print(row(cond + " pooled", "2-4", stats(pooled[cond])))
    print(row("all pooled", "2-4", stats(pooled["same-sun"] + pooled["cross-sun"])))
    steps = [("same-sun step 2 (default, 5 headings)", "same-sun-s2"),
             ("same-sun step 1 (9 headings)", "step1-s2"),
             ("same-sun step 0.5 (9 headings)", "step0.5-s2")]
    if all(os.path.exists(os.path.join(d, n, "traverse.json")) for _, n in steps):
        print()
        print(HEADER)
        for name, n in steps:
            print(row(name, 2, stats(load(d, n))))


if __name__ == "__main__":
    main()
