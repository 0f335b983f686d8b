#!/usr/bin/env python3
"""Replays the fix's choice among its refined candidates, offline: an NCC margin and a
weight of the coarse score.

Usage: python3 scripts/replay_ncc_margin.py [--matcher NAME] REPORT.json [REPORT.json ...]

Reads `orbfix eval --json` reports (the per-query `candidates` of the fix matcher NAME,
default `fix`: position, distance from the truth, NCC score, refined, and `coarse`, the
coarse score of the candidate's window: CNN cosine plus the relief stage's correlation) and
prints, for margins 0 to 0.1 and coarse weights 0 to 1, the share of stops within 1 m and
5 m if each refined peak were scored `ncc + weight * coarse` and the CNN's best peak kept
its refinement unless another refined peak beat its score by more than the margin
(`RefineConfig::ncc_margin_stereo`, `RefineConfig::coarse_weight_stereo`). A replay, not the
fix: a chosen candidate below the kept NCC (0.1) falls back to the report's own error, and
the reach-edge test is not in the report, so the fix's own setting agrees with the report
on most stops, not all (printed). Confirm a setting with `orbfix eval --matcher
fix,fix-nmN,fix-cwN`.
"""
import json
import sys

MIN_NCC = 0.1
MARGINS = [0.0, 0.02, 0.04, 0.05, 0.06, 0.08, 0.1]
WEIGHTS = [0.0, 0.1, 0.2, 0.3, 0.5, 1.0, 2.0]


def fix_report(path, name):
    d = json.load(open(path))
    if isinstance(d, list):
        d = next(x for x in d if x["matcher"] == name)
    return d


def chosen(cands, margin, weight):
    refined = [c for c in cands if c["refined"]]
    if not refined:
        return None

    def total(c):
        return c["score"] + weight * c.get("coarse", 0.0)

    first = refined[0]
    best = max(refined[1:], key=total, default=None)
    if best is not None and total(best) > total(first) + margin:
        return best
    return first


def main():
    args = sys.argv[1:]
    name = "fix"
    if len(args) >= 2 and args[0] == "--matcher":
        name, args = args[1], args[2:]
    if not args:
        sys.exit(__doc__)
    queries = [q for p in args for q in fix_report(p, name)["per_query"]]
    if not queries or "candidates" not in queries[0]:
        sys.exit("replay_ncc_margin: the reports have no candidates (an orbfix older than the field)")
    weights = WEIGHTS
    if any(c.get("coarse") is None for q in queries for c in q["candidates"]):
        print("(no coarse scores in these reports: weight 0 only)")
        weights = [0.0]
    n = len(queries)
    print(f"{n} stops of {name}; within 1 m / within 5 m / the same position as the report")
    print("margin " + "".join(f"| weight {w:<14}" for w in weights))
    for margin in MARGINS:
        cells = []
        for weight in weights:
            within = {1: 0, 5: 0}
            agree = 0
            for q in queries:
                c = chosen(q["candidates"], margin, weight)
                e = c["error_m"] if c is not None and c["score"] >= MIN_NCC else q["error_m"]
                agree += abs(e - q["error_m"]) < 0.01
                within[1] += e <= 1
                within[5] += e <= 5
            cells.append(f"| {within[1] / n:.3f} {within[5] / n:.3f} {agree:>4} ")
        print(f"{margin:.2f}   " + "".join(cells))


if __name__ == "__main__":
    main()
