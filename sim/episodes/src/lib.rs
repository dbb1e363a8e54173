//! dkrrt-episodes: seeded threat episodes for every scene.
//!
//! An episode is a start and a goal configuration that need a real motion (≥ 0.5 rad on some
//! joint; with `episode.max_straight_s`, a straight motion no longer than that, for short
//! runs), the scene's debris, and 1–3 of its objects re-aimed so that the true dynamics
//! (nonlinear relative orbit, tumbling, the scene's perturbations and events) bring them onto
//! a point of the arm's **straight** motion (the jerk-limited line the `straight` method
//! drives) at a chosen time:
//!
//! 1. pick an object, a time `t_hit` in 30–75 % of the straight motion (≥ 2 s, so a predictor
//!    has observed it; a capped episode: 30–60 %, ≥ 1.2 s), a link of the arm and a point on its capsule axis at that time, and a
//!    velocity (the scene's speed range, a random direction);
//! 2. find the object's initial position by **shooting**: start from the straight-line
//!    back-projection `p0 = p_hit − v·t_hit`, simulate the whole scene with the true dynamics
//!    to `t_hit`, move `p0` by the miss, and repeat until the miss is below 1 mm (the relative
//!    dynamics over seconds are close to linear, so three or four rounds do; this is the
//!    backward integration done with the forward integrator, so every perturbation stream and
//!    event of the scene stays exactly as the simulator will replay it);
//! 3. **solvable by construction**: simulate the episode to its time limit and require that no
//!    object ever comes within `REST_CLEARANCE_M` of the arm resting at its start or at its goal
//!    (else draw again). Waiting at the start, or going early and waiting at the goal, is
//!    therefore always possible.
//!
//! The time limit is 3 × the straight motion's duration + 10 s. Everything is a function of
//! (scene, index, seed): every process regenerates the same episode.

use dkrrt_collision::{proximity, ArmPoser, Obstacle, PosedCapsule};
use dkrrt_config::{EpisodeCfg, GoalCfg, Scenario};
use dkrrt_debris::{DebrisWorld, Scene, ShapeSpec, SCENE_NAMES};
use dkrrt_model::NJ;
use dkrrt_otg::{KinState, Limits, Options};
use nalgebra::Vector3;
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use serde::Serialize;

/// Draws of start, goal and threats before an episode is given up.
pub const ATTEMPTS: u32 = 500;

/// No object comes closer than this to the arm at rest at its start or goal, m.
pub const REST_CLEARANCE_M: f64 = 0.3;

/// The clearance kept from the arm at rest: [`REST_CLEARANCE_M`], or 9 % of the arm's reach
/// for a smaller arm (the default arm reaches 3.35 m: 0.3 m; a UR5-sized one 1.29 m:
/// 0.116 m), so the threats that pass its motion can miss its rests.
pub fn rest_clearance_m(poser: &ArmPoser) -> f64 {
    REST_CLEARANCE_M.min(0.09 * poser.reach_sphere().1)
}

/// Earliest threat time of a capped episode, s (a predictor has observed ~60 frames by then).
pub const CAPPED_HIT_S: f64 = 1.2;

/// The motion of an episode's big joint at least, rad.
pub const MIN_MOTION_RAD: f64 = 0.5;

/// One re-aimed object.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Threat {
    pub id: u32,
    /// When its centre reaches the arm point, s.
    pub t_hit_s: f64,
    /// The link and the aimed point (arm base frame) on the straight motion at `t_hit_s`.
    pub link: usize,
    pub point: [f64; 3],
    pub speed_mps: f64,
    /// Remaining miss of the shooting, m.
    pub miss_m: f64,
}

/// A generated episode.
#[derive(Debug, Clone, Serialize)]
pub struct Episode {
    pub scene_name: String,
    pub index: u64,
    pub seed: u64,
    pub start: [f64; NJ],
    pub goal: [f64; NJ],
    #[serde(skip)]
    pub scene: Scene,
    pub straight_duration_s: f64,
    pub time_limit_s: f64,
    pub threats: Vec<Threat>,
    /// Smallest distance of any object to the arm resting at start or goal, m.
    pub rest_clearance_m: f64,
    /// Draws rejected before this one.
    pub attempts: u32,
    /// Background objects taken out because they would reach the arm at rest.
    pub removed_objects: u32,
}

/// Scene parameters: threats and their speed range, m/s.
fn params(scene: &str) -> (usize, f64, f64) {
    match scene {
        "sparse-slow" => (1, 0.15, 0.4),
        "dense" => (3, 0.2, 0.6),
        "fast-crossing" => (2, 0.6, 1.5),
        _ => (2, 0.15, 0.45),
    }
}

/// A scene file's threat parameters: two threats (at most its object count) at speeds
/// between its slowest and its fastest moving object's (0.15–0.45 m/s when none moves).
fn params_of(scene: &Scene) -> (usize, f64, f64) {
    let speeds = scene.debris.iter().map(|d| Vector3::from(d.v).norm()).filter(|v| *v > 1e-6);
    let (lo, hi) = speeds.fold((f64::INFINITY, 0.0f64), |(lo, hi), v| (lo.min(v), hi.max(v)));
    let n = 2.min(scene.debris.len());
    if hi > 0.0 {
        (n, lo.max(0.05).min(hi), hi.max(0.05))
    } else {
        (n, 0.15, 0.45)
    }
}

fn mix(a: u64, b: u64) -> u64 {
    let mut x = a ^ b.wrapping_mul(0x9E37_79B9_7F4A_7C15);
    x ^= x >> 31;
    x = x.wrapping_mul(0xBF58_476D_1CE4_E5B9);
    x ^ (x >> 29)
}

/// The straight (time-synchronized, jerk-limited, rest-to-rest) motion.
pub fn straight(
    start: &[f64; NJ],
    goal: &[f64; NJ],
    lim: &Limits<NJ>,
) -> Result<dkrrt_otg::Trajectory<NJ>, String> {
    dkrrt_otg::Trajectory::calculate(
        &KinState::rest(*start),
        &KinState::rest(*goal),
        lim,
        &Options::default(),
    )
    .map_err(|e| format!("straight motion: {e}"))
}

/// Generates episode `cfg` for the arm, motion limits and base position of `sc`.
pub fn generate(cfg: &EpisodeCfg, sc: &Scenario) -> Result<Episode, String> {
    let named = SCENE_NAMES.iter().position(|s| *s == cfg.scene);
    let (base_scene, scene_key, (n_threats, v_lo, v_hi)) = match (named, sc.scene_file(&cfg.scene)) {
        (Some(ix), _) => {
            (Scene::named(&cfg.scene).map_err(|e| e.to_string())?, ix as u64 + 1, params(&cfg.scene))
        }
        // A scene file: its episodes are keyed by the scene's name (the same file gives the
        // same episodes wherever it lies), its threats move at its own objects' speeds.
        (None, Some(path)) => {
            let scene = Scene::from_file(&path).map_err(|e| format!("episode.scene {:?}: {e}", cfg.scene))?;
            let key = scene
                .name
                .bytes()
                .fold(0xCBF2_9CE4_8422_2325u64, |h, b| (h ^ u64::from(b)).wrapping_mul(0x100_0000_01B3));
            let p = params_of(&scene);
            (scene, key, p)
        }
        (None, None) => {
            return Err(format!(
                "episode.scene {:?}: not a named scene ({}) nor a scene file",
                cfg.scene,
                SCENE_NAMES.join(", ")
            ))
        }
    };
    let model = sc.load_arm().map_err(|e| e.to_string())?;
    let lim = Limits { v_max: sc.motion.v_max, a_max: sc.motion.a_max, j_max: sc.motion.j_max };
    let base = sc.debris.base_lvlh;
    let mut rng = SmallRng::seed_from_u64(mix(mix(cfg.seed, scene_key), cfg.index));
    let poser = ArmPoser::with_offset(model.clone(), base);
    let rest_min = rest_clearance_m(&poser);
    let center = sc.sim.initial_q;
    let ql = model.limits();
    // Why draws were rejected: [small motion, shooting missed, a threat reaches the arm at rest,
    // too many background objects would].
    let mut why = [0u32; 5];
    // A capped episode: the big joint is one whose 0.5 rad motion alone fits the cap.
    let eligible: Vec<usize> = match cfg.max_straight_s {
        None => (0..4).collect(),
        Some(cap) => {
            let alone = |j: usize| -> Result<f64, String> {
                let mut g = [0.0; NJ];
                g[j] = MIN_MOTION_RAD;
                Ok(straight(&[0.0; NJ], &g, &lim)?.duration())
            };
            let mut e = Vec::new();
            let mut fastest = f64::INFINITY;
            for j in 0..4 {
                let d = alone(j)?;
                fastest = fastest.min(d);
                if d <= cap {
                    e.push(j);
                }
            }
            if e.is_empty() {
                return Err(format!(
                    "episode.max_straight_s = {cap} s: shorter than a {MIN_MOTION_RAD} rad motion of any of the \
                     first four joints within motion.v_max/a_max/j_max (fastest: {fastest:.2} s)"
                ));
            }
            e
        }
    };
    let capped = cfg.max_straight_s.is_some();
    for attempt in 0..ATTEMPTS {
        // Start and goal: a real motion (≥ 0.5 rad on one of the first four joints).
        let start: [f64; NJ] = std::array::from_fn(|i| {
            (center[i] + rng.random_range(-0.5..0.5)).clamp(ql.q_min[i] + 0.1, ql.q_max[i] - 0.1)
        });
        let big =
            if !capped { rng.random_range(0..4) } else { eligible[rng.random_range(0..eligible.len())] };
        let mut goal: [f64; NJ] = std::array::from_fn(|i| {
            let d = if i == big {
                rng.random_range(0.5..0.9) * if rng.random::<bool>() { 1.0 } else { -1.0 }
            } else {
                rng.random_range(-0.6..0.6)
            };
            (start[i] + d).clamp(ql.q_min[i] + 0.1, ql.q_max[i] - 0.1)
        });
        if (0..NJ).map(|i| (goal[i] - start[i]).abs()).fold(0.0, f64::max) < MIN_MOTION_RAD {
            why[0] += 1;
            continue;
        }
        let mut tr = straight(&start, &goal, &lim)?;
        if let Some(cap) = cfg.max_straight_s {
            // Shrink the motion (the big joint no further than 0.5 rad) until it fits the cap.
            let mut rounds = 0;
            while tr.duration() > cap && rounds < 30 {
                for i in 0..NJ {
                    let d = goal[i] - start[i];
                    let floor = if i == big { MIN_MOTION_RAD.min(d.abs()) } else { 0.0 };
                    goal[i] = start[i] + d.signum() * (0.85 * d.abs()).max(floor);
                }
                tr = straight(&start, &goal, &lim)?;
                rounds += 1;
            }
            if tr.duration() > cap {
                why[4] += 1;
                continue;
            }
        }
        let d = tr.duration();
        let time_limit = 3.0 * d + 10.0;
        let mut scene = base_scene.clone();
        scene.seed = rng.random();
        // Threat objects: rods and panels first in tumbling-rods (predicted attitude matters).
        let mut pool: Vec<usize> = (0..scene.debris.len()).collect();
        if cfg.scene == "tumbling-rods" {
            pool.sort_by_key(|&i| {
                !matches!(scene.debris[i].shape, ShapeSpec::Rod { .. } | ShapeSpec::Panel { .. })
            });
            pool.truncate(4);
        }
        let mut threats: Vec<(usize, Threat)> = Vec::new();
        let mut ok = true;
        for _ in 0..n_threats.min(pool.len()) {
            let k = pool.swap_remove(rng.random_range(0..pool.len()));
            match aim(&mut scene, k, &tr, &poser, (v_lo, v_hi), base, capped, &mut rng)? {
                Some(t) => threats.push((k, t)),
                None => {
                    why[1] += 1;
                    ok = false;
                    break;
                }
            }
        }
        if !ok {
            continue;
        }
        // Solvable by construction: a threat that reaches the arm resting at its start or goal
        // is aimed again (up to 8 times); background objects that would are taken out of the
        // episode (with their events).
        let mut removed = 0;
        let mut re_aims = 0;
        let rest = loop {
            let (rest, id) = rest_clearance(&scene, &poser, &start, &goal, time_limit)?;
            if rest >= rest_min {
                break Some(rest);
            }
            if let Some(ti) = threats.iter().position(|t| t.1.id == id) {
                re_aims += 1;
                if re_aims > 16 {
                    why[2] += 1;
                    break None;
                }
                let k = threats[ti].0;
                match aim(&mut scene, k, &tr, &poser, (v_lo, v_hi), base, capped, &mut rng)? {
                    Some(t) => threats[ti].1 = t,
                    None => {
                        why[1] += 1;
                        break None;
                    }
                }
                continue;
            }
            if removed >= 8 {
                why[3] += 1;
                break None;
            }
            scene.events.retain(|e| match e {
                dkrrt_debris::EventSpec::Impulse { id: i, .. } => *i != id,
                dkrrt_debris::EventSpec::Split { id: i, new_id, .. } => *i != id && *new_id != id,
            });
            scene.debris.retain(|o| o.id != id);
            // Indices of the threats after the removal.
            for t in threats.iter_mut() {
                t.0 = scene.debris.iter().position(|o| o.id == t.1.id).unwrap_or(t.0);
            }
            removed += 1;
        };
        let Some(mut rest) = rest else { continue };
        if removed > 0 {
            // Removing objects re-orders the scene's perturbation streams: aim the threats
            // once more at their points (a millimetre correction), then check the rests again.
            let mut on_target = true;
            for (k, t) in threats.iter_mut() {
                let d = &scene.debris[*k];
                let v = Vector3::from(d.v);
                let target = Vector3::new(t.point[0] + base[0], t.point[1] + base[1], t.point[2] + base[2]);
                t.miss_m = shoot(&mut scene, *k, t.t_hit_s, &target, &v)?;
                on_target &= t.miss_m <= 1e-3;
            }
            let (r, _) = rest_clearance(&scene, &poser, &start, &goal, time_limit)?;
            if !on_target || r < rest_min {
                why[2] += 1;
                continue;
            }
            rest = r;
        }
        return Ok(Episode {
            scene_name: cfg.scene.clone(),
            index: cfg.index,
            seed: cfg.seed,
            start,
            goal,
            scene,
            straight_duration_s: d,
            time_limit_s: time_limit,
            threats: threats.into_iter().map(|t| t.1).collect(),
            rest_clearance_m: rest,
            attempts: attempt,
            removed_objects: removed,
        });
    }
    Err(format!(
        "episode {:?} #{} (seed {}): no solvable draw in {ATTEMPTS} attempts (rejected: {} small motions, {} missed aims, \
         {} threats reaching the arm at rest, {} with too many background objects doing so, {} motions \
         longer than episode.max_straight_s)",
        cfg.scene, cfg.index, cfg.seed, why[0], why[1], why[2], why[3], why[4]
    ))
}

/// Aims object `k` at a point of the arm on the straight motion `tr` (see the crate docs);
/// `None` when the shooting does not converge.
#[allow(clippy::too_many_arguments)]
fn aim(
    scene: &mut Scene,
    k: usize,
    tr: &dkrrt_otg::Trajectory<NJ>,
    poser: &ArmPoser,
    (v_lo, v_hi): (f64, f64),
    base: [f64; 3],
    capped: bool,
    rng: &mut SmallRng,
) -> Result<Option<Threat>, String> {
    let d = tr.duration();
    // A short (capped) motion is hit near its middle, from 1.2 s on: later, the arm is nearly
    // at its goal and no draw keeps the goal pose clear.
    let t_hit = if capped {
        (rng.random_range(0.3..0.6) * d).max(CAPPED_HIT_S).min(d)
    } else {
        (rng.random_range(0.3..0.75) * d).max(2.0).min(d)
    };
    let q_hit = tr.at(t_hit).p;
    let q_next = tr.at(t_hit + 0.05).p;
    let (mut caps, mut caps_next) = ([PosedCapsule::default(); NJ], [PosedCapsule::default(); NJ]);
    poser.pose(&q_hit, &mut caps);
    poser.pose(&q_next, &mut caps_next);
    let link = rng.random_range(3..NJ);
    let u = rng.random_range(0.4..1.0);
    let at = |c: &PosedCapsule| {
        Vector3::new(
            c.a[0] + u * (c.b[0] - c.a[0]),
            c.a[1] + u * (c.b[1] - c.a[1]),
            c.a[2] + u * (c.b[2] - c.a[2]),
        )
    };
    let target = at(&caps[link]);
    // Across the surface the link sweeps (normal to the link and to its motion), so the object
    // crosses the straight motion once, away from the start and goal poses.
    let c = caps[link];
    let axis = Vector3::new(c.b[0] - c.a[0], c.b[1] - c.a[1], c.b[2] - c.a[2]);
    let motion = at(&caps_next[link]) - target;
    let mut normal = axis.cross(&motion);
    if normal.norm() < 1e-9 {
        normal = axis.cross(&Vector3::new(0.3, 0.5, 0.8));
    }
    let speed = rng.random_range(v_lo..v_hi);
    let sign = if rng.random::<bool>() { 1.0 } else { -1.0 };
    let dir = loop {
        let v = Vector3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        if v.norm() <= 1.0 {
            break (normal.normalize() * sign + v * 0.35).normalize();
        }
    };
    let v = dir * speed;
    let p0 = target - v * t_hit;
    scene.debris[k].p = [p0.x, p0.y, p0.z];
    let miss = shoot(scene, k, t_hit, &target, &v)?;
    if miss > 1e-3 {
        return Ok(None);
    }
    Ok(Some(Threat {
        id: scene.debris[k].id,
        t_hit_s: t_hit,
        link,
        point: [target.x - base[0], target.y - base[1], target.z - base[2]],
        speed_mps: speed,
        miss_m: miss,
    }))
}

/// Sets object `k`'s initial state so that the true dynamics bring its centre to `target` (LVLH)
/// at `t_hit` with about velocity `v`. Returns the remaining miss, m.
fn shoot(
    scene: &mut Scene,
    k: usize,
    t_hit: f64,
    target: &Vector3<f64>,
    v: &Vector3<f64>,
) -> Result<f64, String> {
    let id = scene.debris[k].id;
    let p0 = target - v * t_hit;
    scene.debris[k].p = [p0.x, p0.y, p0.z];
    scene.debris[k].v = [v.x, v.y, v.z];
    let mut miss = f64::INFINITY;
    for _ in 0..6 {
        let mut w = DebrisWorld::new(scene).map_err(|e| e.to_string())?;
        // Only the object's own motion matters here: step it alone (exactly as in the whole).
        w.set_only(Some(id));
        w.set_translation_only(true);
        let n = (t_hit / 0.01).round().max(1.0) as usize;
        for _ in 0..n {
            w.step(t_hit / n as f64);
        }
        let Some(i) = w.index_of(id) else { return Ok(f64::INFINITY) };
        let err = target - w.debris()[i].state.p;
        miss = err.norm();
        if miss < 1e-4 {
            break;
        }
        let d = &mut scene.debris[k].p;
        d[0] += err.x;
        d[1] += err.y;
        d[2] += err.z;
    }
    Ok(miss)
}

/// Smallest distance of any object to the arm resting at `start` or `goal` over `[0, t_end]`
/// (stops at the first object found within [`rest_clearance_m`], and names it).
fn rest_clearance(
    scene: &Scene,
    poser: &ArmPoser,
    start: &[f64; NJ],
    goal: &[f64; NJ],
    t_end: f64,
) -> Result<(f64, u32), String> {
    let rest_min = rest_clearance_m(poser);
    let mut w = DebrisWorld::new(scene).map_err(|e| e.to_string())?;
    // Steps in which no object moves more than about 4 cm: 0.02 s up to 2 m/s (the named
    // scenes' fastest object starts at 2 m/s; 2.05 leaves their episodes as they were), less
    // for a scene file's faster objects.
    let fastest = w.debris().iter().map(|d| d.state.v.norm()).fold(0.0, f64::max);
    let dt = if fastest <= 2.05 { 0.02 } else { 0.04 / fastest };
    let (mut cs, mut cg) = ([PosedCapsule::default(); NJ], [PosedCapsule::default(); NJ]);
    poser.pose(start, &mut cs);
    poser.pose(goal, &mut cg);
    let mut obs = Vec::with_capacity(dkrrt_debris::MAX_DEBRIS);
    let mut best = f64::INFINITY;
    let n = (t_end / dt).ceil() as usize;
    for _ in 0..=n {
        obs.clear();
        for d in w.debris() {
            let q = d.state.q.quaternion();
            obs.push(Obstacle::from_shape(
                d.id,
                &d.props.shape,
                d.props.bounding_radius,
                &[d.state.p.x, d.state.p.y, d.state.p.z],
                &[q.w, q.i, q.j, q.k],
            ));
        }
        // Steps of at most 4 cm of any object's motion: inside the clearance asked.
        let (a, b) = (proximity(&cs, &obs, 0.0, &mut []), proximity(&cg, &obs, 0.0, &mut []));
        let (m, id) =
            if a.min_distance < b.min_distance { (a.min_distance, a.id) } else { (b.min_distance, b.id) };
        best = best.min(m);
        if m < rest_min {
            return Ok((m, id));
        }
        w.step(dt);
    }
    Ok((best, u32::MAX))
}

/// Resolves `sc.episode` (if any) into the scenario: start, goal, the generated scene, the
/// time limit as the run's duration. Returns the episode.
pub fn resolve(sc: &mut Scenario) -> Result<Option<Episode>, String> {
    let Some(cfg) = sc.episode.clone() else { return Ok(None) };
    let ep = generate(&cfg, sc)?;
    sc.sim.initial_q = ep.start;
    sc.goal = if cfg.pose_goal {
        // The end-effector pose of the goal configuration.
        let model = sc.load_arm().map_err(|e| e.to_string())?;
        let x = model.fk(&dkrrt_model::JVec::from_row_slice(&ep.goal));
        let (t, r) = (x.translation.vector, x.rotation.quaternion());
        GoalCfg { q: None, pose: Some([t.x, t.y, t.z, r.w, r.i, r.j, r.k]) }
    } else {
        GoalCfg::joint(ep.goal)
    };
    sc.debris.scene = cfg.scene.clone();
    sc.scene_override = Some(ep.scene.clone());
    sc.episode_time_limit_s = Some(ep.time_limit_s);
    sc.run.duration_s = cfg.duration_s.unwrap_or(ep.time_limit_s);
    Ok(Some(ep))
}
