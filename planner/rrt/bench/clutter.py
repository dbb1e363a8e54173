#!/usr/bin/env python3
"""Random still planning problems for `dkrrt plan` (docs/planning-problem.md): the shipped arm,
a random start and goal (within 80 % of each joint's range) and N random obstacles (spheres,
boxes, capsules; random attitudes) 0.8-2.9 m from the base, each with one pose.

    python3 planner/rrt/bench/clutter.py SEED COUNT OBSTACLES OUTDIR
    for f in OUTDIR/*.json; do target/release/dkrrt plan --problem $f --time-limit 1; done

Some problems have the start or the goal in collision: `dkrrt plan` says so and they count as
unsolvable. The figures in planner/rrt/README.md ("Problem files") come from these commands.
"""
import json, math, os, random, sys

seed, count, n_obs, out = int(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
lim = [4.71, 2.96, 2.96, 2.96, 2.96, 4.71]
os.makedirs(out, exist_ok=True)
for k in range(count):
    r = random.Random(seed * 1000 + k)
    start = [r.uniform(-l * 0.8, l * 0.8) for l in lim]
    goal = [r.uniform(-l * 0.8, l * 0.8) for l in lim]
    obstacles = []
    for _ in range(n_obs):
        while True:
            p = [r.uniform(-2.8, 2.8) for _ in range(3)]
            if 0.8 < math.sqrt(sum(x * x for x in p)) < 2.9:
                break
        kind = r.choice(["sphere", "box", "capsule"])
        if kind == "sphere":
            shape = {"kind": "sphere", "radius": r.uniform(0.1, 0.3)}
        elif kind == "box":
            shape = {"kind": "box", "half_extents": [r.uniform(0.05, 0.3) for _ in range(3)]}
        else:
            shape = {"kind": "capsule", "half_length": r.uniform(0.1, 0.5), "radius": r.uniform(0.03, 0.15)}
        q = [r.gauss(0, 1) for _ in range(4)]
        n = math.sqrt(sum(x * x for x in q))
        obstacles.append({"shape": shape, "poses": [{"t": 0.0, "p": p, "q": [x / n for x in q]}]})
    problem = {"urdf": "", "start": start, "goal": goal, "margin_m": 0.0, "time_limit_s": 1.0,
               "seed": 1, "obstacles": obstacles}
    with open(os.path.join(out, f"p{seed}_{k:03d}.json"), "w") as f:
        json.dump(problem, f)
