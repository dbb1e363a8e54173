#!/usr/bin/env python3
"""dkrrt plan against OMPL on the same planning-problem files, with the same checks.

    python3 planner/cabi/bench/compare.py DIR [--time-limit 1] [--planners rrtconnect,bitstar]

Builds `dkrrt` and the C ABI (`cargo build --release`), compiles bench/ompl_compare.cpp against
the system's OMPL (Debian/Ubuntu: `apt-get install libompl-dev`), then solves every DIR/*.json
with `dkrrt plan` and with each OMPL planner. OMPL plans through dkrrt's own checks (the C ABI:
the state and segment checks of dkrrt's RRT-Connect), its path is timed by dkrrt's rest-to-rest
motions and given the same final check: only the planning algorithm differs. Only still
problems whose start and goal are clear count (joint-space problems; the others are listed).
Prints one table; --json FILE writes every row; --table FILE prints the table of such a file.
"""
import argparse, glob, json, os, statistics, subprocess, sys

here = os.path.dirname(os.path.abspath(__file__))
root = os.path.abspath(os.path.join(here, "..", "..", ".."))
ap = argparse.ArgumentParser()
ap.add_argument("dir", nargs="?")
ap.add_argument("--time-limit", type=float, default=1.0)
ap.add_argument("--planners", default="rrtconnect,bitstar")
ap.add_argument("--json")
ap.add_argument("--table", help="print the table of a --json file (nothing is run)")
a = ap.parse_args()


def med(xs):
    xs = [x for x in xs if x is not None]
    return statistics.median(xs) if xs else float("nan")


def table(rows, names, still):
    """rows: (planner, file) -> row; names: dkrrt first; still: the files compared."""
    print(f"{'planner':<17} {'solved':>7} {'first ms p50 / max':>20} {'configs to first p50':>21} "
          f"{'duration s p50':>15} {'path rad p50':>13} {'waypoints p50':>14}")
    for n in names:
        rs = [rows[(n, f)] for f in still if (n, f) in rows]
        ok = [r for r in rs if r["solved"]]
        fs = [1e3 * r["first_solution_s"] for r in ok if r.get("first_solution_s") is not None]
        print(f"{n:<17} {len(ok):>3}/{len(rs):<3} {med(fs):>9.2f} / {max(fs, default=float('nan')):>8.2f} "
              f"{med([r.get('first_solution_configs') for r in ok]):>21.0f} "
              f"{med([r['duration_s'] for r in ok]):>15.2f} {med([r['path_length_rad'] for r in ok]):>13.2f} "
              f"{med([r['waypoints'] for r in ok]):>14.0f}")
    print("Paired with dkrrt, on the problems both solved (ratio = OMPL / dkrrt; > 1: dkrrt better):")
    for n in names[1:]:
        both = [f for f in still if rows.get(("dkrrt", f), {}).get("solved") and rows.get((n, f), {}).get("solved")]
        if not both:
            print(f"  {n}: no problem solved by both")
            continue
        d = [rows[(n, f)]["duration_s"] / rows[("dkrrt", f)]["duration_s"] for f in both]
        t = [rows[(n, f)]["first_solution_s"] / rows[("dkrrt", f)]["first_solution_s"] for f in both]
        only_d = sum(1 for f in still if rows.get(("dkrrt", f), {}).get("solved") and not rows.get((n, f), {}).get("solved"))
        only_o = sum(1 for f in still if rows.get((n, f), {}).get("solved") and not rows.get(("dkrrt", f), {}).get("solved"))
        print(f"  {n}: {len(both)} both; duration ratio p50 {med(d):.2f}, mean {statistics.mean(d):.2f} "
              f"(dkrrt shorter in {sum(x > 1.001 for x in d)}, longer in {sum(x < 0.999 for x in d)}, the same "
              f"in the rest); first-solution time ratio p50 {med(t):.2f} (dkrrt sooner in {sum(x > 1 for x in t)}); "
              f"solved by dkrrt only {only_d}, by {n} only {only_o}")


if a.table:
    saved = json.load(open(a.table))
    rows = {(r["planner"], r["file"]): r for r in saved}
    names = ["dkrrt"] + sorted({r["planner"] for r in saved if r["planner"] != "dkrrt"}, key=lambda x: x != "ompl-rrtconnect")
    still = sorted({r["file"] for r in saved if r["planner"] != "dkrrt" and r.get("still")})
    table(rows, names, still)
    sys.exit(0)
if not a.dir:
    sys.exit("compare.py: give a DIR of problem files (or --table FILE)")

target = os.environ.get("CARGO_TARGET_DIR", os.path.join(root, "target"))
subprocess.run(["cargo", "build", "--release", "-q", "-p", "dkrrt", "-p", "dkrrt-plan-cabi"], cwd=root, check=True)
inc = "/usr/include/ompl-1.5"
if not os.path.isdir(inc):
    cands = sorted(glob.glob("/usr/include/ompl-*")) + sorted(glob.glob("/usr/local/include/ompl-*"))
    if not cands:
        sys.exit("compare.py: OMPL's headers are not installed (Debian/Ubuntu: apt-get install libompl-dev)")
    inc = cands[-1]
harness = os.path.join(target, "release", "ompl_compare")
subprocess.run(["g++", "-O2", "-std=c++17", f"-I{inc}", "-I/usr/include/eigen3",
                os.path.join(here, "ompl_compare.cpp"), "-o", harness,
                os.path.join(target, "release", "libdkrrt_plan_cabi.a"), "-lompl", "-lpthread", "-ldl", "-lm"],
               check=True)
files = sorted(glob.glob(os.path.join(a.dir, "*.json")))
if not files:
    sys.exit(f"compare.py: no *.json in {a.dir}")

rows = {}  # (planner, file) -> row
for f in files:
    out = f + ".dkrrt-plan.out"
    r = subprocess.run([os.path.join(target, "release", "dkrrt"), "plan", "--problem", f,
                        "--time-limit", str(a.time_limit), "--json", out], capture_output=True, text=True)
    if not os.path.exists(out):  # (an unsolved problem exits with 1, its file written)
        sys.exit(f"{f}: dkrrt plan failed: {r.stderr.strip()}")
    s = json.load(open(out))
    os.remove(out)
    rows[("dkrrt", f)] = {"file": f, "planner": "dkrrt", "solved": s["solved"],
                          "first_solution_s": s["first_solution_s"], "plan_time_s": s["plan_time_s"],
                          "first_solution_configs": s.get("first_solution_configs"),
                          "configs_checked": s.get("configs_checked"), "duration_s": s["duration_s"],
                          "path_length_rad": s["path_length_rad"], "waypoints": len(s["path"]),
                          "min_clearance_m": s["min_clearance_m"], "passed": s["solved"]}
planners = [p for p in a.planners.split(",") if p]
still = None
for p in planners:
    r = subprocess.run([harness, p, str(a.time_limit)] + files, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"ompl_compare {p}: {r.stderr.strip()}")
    for line in r.stdout.splitlines():
        x = json.loads(line)
        x["planner"] = "ompl-" + p
        x["solved"] = bool(x.get("solved")) and bool(x.get("passed"))
        rows[(x["planner"], x["file"])] = x
    still = {x["file"] for (q, _), x in rows.items() if q == "ompl-" + p and x["still"]}
if still is None:
    sys.exit("compare.py: no OMPL planner given")
skipped = [f for f in files if f not in still]
print(f"{len(files)} problems in {a.dir}; {len(still)} still with the start and goal clear "
      f"(compared); {len(skipped)} others (moving obstacles, or the start or goal within δ/2 "
      f"of an obstacle) left out. Time limit {a.time_limit} s each.")

names = ["dkrrt"] + ["ompl-" + p for p in planners]
table(rows, names, sorted(still))
if a.json:
    json.dump(list(rows.values()), open(a.json, "w"), indent=1)
