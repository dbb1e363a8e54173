#!/usr/bin/env python3
"""dkrrt plan against OMPL on the same planning-problem files, with the same checks.

    python3 planner/cabi/bench/compare.py DIR [--time-limit 1] [--planners rrtconnect,bitstar] [--seeds N]

Builds `dkrrt` and the C ABI (`cargo build --release`), compiles bench/ompl_compare.cpp against
the system's OMPL (Debian/Ubuntu: `apt-get install libompl-dev`), then solves every DIR/*.json
with `dkrrt plan` and with each OMPL planner. OMPL plans through dkrrt's own checks (the C ABI:
the state and segment checks of dkrrt's RRT-Connect), its path is timed by dkrrt's rest-to-rest
motions and given the same final check: only the planning algorithm differs. Only still
problems whose start and goal are clear count (joint-space problems; the others are listed).
--seeds N solves every problem N times, with seeds 1..N in place of the file's (the time to a
first solution of one run is mostly luck: its spread over runs is the figure to compare); the
table's first-solution columns are then over all runs, the paired ratios compare each problem's
medians over its runs.
Prints one table; --json FILE writes every row; --table FILE prints the table of such a file.
"""
import argparse, glob, json, os, statistics, subprocess, sys

here = os.path.dirname(os.path.abspath(__file__))
root = os.path.abspath(os.path.join(here, "..", "..", ".."))
ap = argparse.ArgumentParser()
ap.add_argument("dir", nargs="?")
ap.add_argument("--time-limit", type=float, default=1.0)
ap.add_argument("--planners", default="rrtconnect,bitstar")
ap.add_argument("--seeds", type=int, default=1, help="runs per problem, seeds 1..N (1: the file's own seed)")
ap.add_argument("--json")
ap.add_argument("--table", help="print the table of a --json file (nothing is run)")
a = ap.parse_args()


def med(xs):
    xs = [x for x in xs if x is not None]
    return statistics.median(xs) if xs else float("nan")


def pct(xs, q):
    xs = sorted(x for x in xs if x is not None)
    return xs[min(len(xs) - 1, int(q * len(xs)))] if xs else float("nan")


def table(rows, names, still, problem_of):
    """rows: (planner, run file) -> row; names: dkrrt first; still: the run files compared;
    problem_of: run file -> its problem file (runs of one problem differ in the seed only)."""
    problems = sorted({problem_of(f) for f in still})
    runs = {p: [f for f in still if problem_of(f) == p] for p in problems}
    print(f"{len(problems)} problems, {len(still)} runs")
    print(f"{'planner':<17} {'solved runs':>11} {'first ms p50 / p90 / max':>26} {'configs to first p50 / p90':>27} "
          f"{'duration s p50':>15} {'path rad p50':>13} {'waypoints p50':>14}")
    for n in names:
        rs = [rows[(n, f)] for f in still if (n, f) in rows]
        ok = [r for r in rs if r["solved"]]
        fs = [1e3 * r["first_solution_s"] for r in ok if r.get("first_solution_s") is not None]
        cs = [r.get("first_solution_configs") for r in ok]
        print(f"{n:<17} {len(ok):>5}/{len(rs):<5} {med(fs):>9.2f} / {pct(fs, 0.9):>6.2f} / {max(fs, default=float('nan')):>6.1f} "
              f"{med(cs):>18.0f} / {pct(cs, 0.9):>6.0f} "
              f"{med([r['duration_s'] for r in ok]):>15.2f} {med([r['path_length_rad'] for r in ok]):>13.2f} "
              f"{med([r['waypoints'] for r in ok]):>14.0f}")
    print("Paired with dkrrt, per problem (its medians over its runs), on the problems both solved in "
          "every run (ratio = OMPL / dkrrt; > 1: dkrrt better):")

    def solved(n, p):
        return all(rows.get((n, f), {}).get("solved") for f in runs[p])

    def pm(n, p, k):
        return med([rows[(n, f)][k] for f in runs[p]])

    for n in names[1:]:
        both = [p for p in problems if solved("dkrrt", p) and solved(n, p)]
        if not both:
            print(f"  {n}: no problem solved by both")
            continue
        d = [pm(n, p, "duration_s") / pm("dkrrt", p, "duration_s") for p in both]
        t = [pm(n, p, "first_solution_s") / pm("dkrrt", p, "first_solution_s") for p in both]
        only_d = sum(1 for p in problems if solved("dkrrt", p) and not solved(n, p))
        only_o = sum(1 for p in problems if solved(n, p) and not solved("dkrrt", p))
        print(f"  {n}: {len(both)} both; duration ratio p50 {med(d):.2f}, mean {statistics.mean(d):.2f} "
              f"(dkrrt shorter in {sum(x > 1.001 for x in d)}, longer in {sum(x < 0.999 for x in d)}, the same "
              f"in the rest); first-solution time ratio p50 {med(t):.2f} (dkrrt sooner in {sum(x > 1 for x in t)}); "
              f"solved (every run) by dkrrt only {only_d}, by {n} only {only_o}")


if a.table:
    saved = json.load(open(a.table))
    rows = {(r["planner"], r["file"]): r for r in saved}
    names = ["dkrrt"] + sorted({r["planner"] for r in saved if r["planner"] != "dkrrt"}, key=lambda x: x != "ompl-rrtconnect")
    still = sorted({r["file"] for r in saved if r["planner"] != "dkrrt" and r.get("still")})
    origin = {r["file"]: r.get("problem", r["file"]) for r in saved}
    table(rows, names, still, lambda f: origin.get(f, f))
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
problems = sorted(glob.glob(os.path.join(a.dir, "*.json")))
if not problems:
    sys.exit(f"compare.py: no *.json in {a.dir}")
# The runs: each problem as it is, or once per seed 1..N (copies in a temporary directory).
origin = {}
if a.seeds > 1:
    import tempfile
    tmp = tempfile.mkdtemp(prefix="dkrrt-compare-")
    files = []
    for p in problems:
        doc = json.load(open(p))
        # The copies live elsewhere: a URDF named relative to the problem file is made absolute.
        if doc.get("urdf") and not os.path.isabs(doc["urdf"]):
            doc["urdf"] = os.path.abspath(os.path.join(os.path.dirname(p), doc["urdf"]))
        for k in range(1, a.seeds + 1):
            doc["seed"] = k
            f = os.path.join(tmp, f"{os.path.splitext(os.path.basename(p))[0]}.seed{k}.json")
            json.dump(doc, open(f, "w"))
            files.append(f)
            origin[f] = p
else:
    files = problems
    origin = {p: p for p in problems}

rows = {}  # (planner, file) -> row
for f in files:
    out = f + ".dkrrt-plan.out"
    r = subprocess.run([os.path.join(target, "release", "dkrrt"), "plan", "--problem", f,
                        "--time-limit", str(a.time_limit), "--json", out], capture_output=True, text=True)
    if not os.path.exists(out):  # (an unsolved problem exits with 1, its file written)
        sys.exit(f"{f}: dkrrt plan failed: {r.stderr.strip()}")
    s = json.load(open(out))
    os.remove(out)
    rows[("dkrrt", f)] = {"file": f, "problem": origin[f], "planner": "dkrrt", "solved": s["solved"],
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
        x["problem"] = origin[x["file"]]
        x["solved"] = bool(x.get("solved")) and bool(x.get("passed"))
        rows[(x["planner"], x["file"])] = x
    still = {x["file"] for (q, _), x in rows.items() if q == "ompl-" + p and x["still"]}
if still is None:
    sys.exit("compare.py: no OMPL planner given")
n_still = len({origin[f] for f in still})
print(f"{len(problems)} problems in {a.dir}; {n_still} still with the start and goal clear "
      f"(compared); {len(problems) - n_still} others (moving obstacles, or the start or goal within δ/2 "
      f"of an obstacle) left out. Time limit {a.time_limit} s each; {a.seeds} run(s) per problem.")

names = ["dkrrt"] + ["ompl-" + p for p in planners]
table(rows, names, sorted(still), lambda f: origin[f])
if a.json:
    json.dump(list(rows.values()), open(a.json, "w"), indent=1)
if a.seeds > 1:
    import shutil
    shutil.rmtree(tmp, ignore_errors=True)
