#!/usr/bin/env python3
"""Replays the fix's choice among its refined candidates with an NCC margin, offline.

Usage: python3 scripts/replay_ncc_margin.py REPORT.json [REPORT.json ...]

Reads `orbfix eval --json` reports (the `fix` matcher's per-query `candidates`: position,
distance from the truth, NCC score, refined) and prints, for margins 0 to 0.1, the share of
stops within 1 m and 5 m if the CNN's best peak kept its refinement unless another refined
peak beat its NCC by more than the margin (`RefineConfig::ncc_margin_stereo`). A replay, not
the fix: a chosen candidate below the kept NCC (0.1) falls back to the report's own error,
and the reach-edge test is not in the report, so margin 0 agrees with the fix on most stops,
not all (printed). Confirm a margin with `orbfix eval --matcher fix,fix-nmN`.
"""
import json
import sys

MIN_NCC = 0.1


def fix_report(path):
    d = json.load(open(path))
    if isinstance(d, list):
        d = next(x for x in d if x["matcher"] == "fix")
    return d


def chosen(cands, margin):
    refined = [c for c in cands if c["refined"]]
    if not refined:
        return None
    first = refined[0]
    best = max(refined[1:], key=lambda c: c["score"], default=None)
    if best is not None and best["score"] > first["score"] + margin:
        return best
    return first


def main():
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    queries = [q for p in sys.argv[1:] for q in fix_report(p)["per_query"]]
    if not queries or "candidates" not in queries[0]:
        sys.exit("replay_ncc_margin: the reports have no candidates (an orbfix older than the field)")
    for margin in [0.0, 0.02, 0.04, 0.05, 0.06, 0.08, 0.1]:
        within = {1: 0, 5: 0}
        agree = 0
        for q in queries:
            c = chosen(q["candidates"], margin)
            e = c["error_m"] if c is not None and c["score"] >= MIN_NCC else q["error_m"]
            agree += abs(e - q["error_m"]) < 0.01
            within[1] += e <= 1
            within[5] += e <= 5
        n = len(queries)
        print(f"margin {margin:.2f}: within 1 m {within[1] / n:.3f}, within 5 m {within[5] / n:.3f}"
              f" ({n} stops; the same position as the report on {agree})")


if __name__ == "__main__":
    main()
