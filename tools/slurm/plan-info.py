#!/usr/bin/env python3
"""What the Slurm scripts need from a plan (spec §16.1), without jq.

    plan-info.py subsets PLAN   # M, the plan's subset count
    plan-info.py rebuild PLAN   # the subsets to build, as an sbatch --array list ("0-7", "4,5,6")
"""

import json
import sys


def ranges(ids):
    """Compresses sorted ids into sbatch's list syntax: 0-3,5,7-8."""
    out, start, prev = [], None, None
    for i in ids + [None]:
        if start is not None and (i is None or i != prev + 1):
            out.append(str(start) if start == prev else f"{start}-{prev}")
            start = None
        if i is not None and start is None:
            start = i
        prev = i
    return ",".join(out)


def main():
    if len(sys.argv) != 3 or sys.argv[1] not in ("subsets", "rebuild"):
        sys.exit(__doc__)
    with open(sys.argv[2]) as f:
        plan = json.load(f)
    if plan.get("format") != "oocfmt-plan":
        sys.exit(f"{sys.argv[2]}: not an oocfmt plan")
    m = int(plan["subsets"])
    if sys.argv[1] == "subsets":
        print(m)
        return
    reused = {int(r["index"]) for r in plan.get("reuse", [])}
    todo = [i for i in range(m) if i not in reused]
    print(ranges(todo))


if __name__ == "__main__":
    main()
