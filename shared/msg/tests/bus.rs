//! Real iceoryx2 round trips through the contract's bus wrappers.

use dkrrt_msg::bus::{remove_run_leftovers, run_config, Bus};
use dkrrt_msg::*;

fn run_id(tag: &str) -> String {
    format!("t{}-{tag}-{}", std::process::id(), dkrrt_rt::clock::mono_ns() % 1_000_000_000)
}

/// Removes the run's leftover files when dropped (declare before the run's buses, so it is
/// dropped after them).
struct Leftovers(String);

impl Drop for Leftovers {
    fn drop(&mut self) {
        remove_run_leftovers(&self.0);
    }
}

fn shm_files(run: &str) -> usize {
    let prefix = format!("dkrrt_{run}_");
    std::fs::read_dir("/dev/shm")
        .unwrap()
        .flatten()
        .filter(|e| e.file_name().to_string_lossy().starts_with(&prefix))
        .count()
}

fn lim() -> ContractLimits {
    ContractLimits::symmetric(3.0, 2.0, 100.0)
}

fn state(q0: f64) -> RobotState {
    let mut s = <RobotState as Zeroed>::zeroed();
    s.q[0] = q0;
    s.header.stamp_ns = 42;
    s
}

#[test]
fn state_round_trip_stamps_header_and_validates() {
    let run = run_id("rt");
    let _clean = Leftovers(run.clone());
    let a = Bus::new(&run, "a").unwrap();
    let b = Bus::new(&run, "b").unwrap();
    let mut p = a.publisher::<RobotState>(Source::Sim).unwrap();
    let mut s = b.subscriber::<RobotState>().unwrap();
    p.update_connections().unwrap();

    p.publish(&mut state(0.5)).unwrap();
    let mut bad = state(f64::NAN);
    p.publish(&mut bad).unwrap();
    let mut out_of_range = state(10.0);
    p.publish(&mut out_of_range).unwrap();

    let mut got = <RobotState as Zeroed>::zeroed();
    assert!(s.latest(&mut got, &lim()).unwrap());
    assert_eq!(got.q[0], 0.5);
    assert_eq!(got.header.seq, 0);
    assert_eq!(got.header.stamp_ns, 42);
    assert_eq!(got.header.source, Source::Sim as u32);
    assert!(got.header.mono_ns > 0);
    assert_eq!(s.received, 3);
    assert_eq!(s.rejected, 2);
    assert!(matches!(s.last_error, Some(ValidationError::OutOfRange { field: "q", index: 0, .. })));
    // Nothing more queued.
    assert!(!s.latest(&mut got, &lim()).unwrap());
}

#[test]
fn latest_keeps_only_the_newest_sample() {
    let run = run_id("latest");
    let _clean = Leftovers(run.clone());
    let a = Bus::new(&run, "a").unwrap();
    let mut p = a.publisher::<RobotState>(Source::Sim).unwrap();
    let mut s = a.subscriber::<RobotState>().unwrap();
    p.update_connections().unwrap();
    for i in 0..10 {
        p.publish(&mut state(i as f64 * 0.1)).unwrap();
    }
    let mut got = <RobotState as Zeroed>::zeroed();
    assert!(s.latest(&mut got, &lim()).unwrap());
    assert_eq!(got.header.seq, 9);
    assert!((got.q[0] - 0.9).abs() < 1e-12);
}

#[test]
fn late_subscriber_gets_the_last_trajectory() {
    let run = run_id("hist");
    let _clean = Leftovers(run.clone());
    let a = Bus::new(&run, "a").unwrap();
    let mut p = a.publisher::<Trajectory>(Source::TrajectorySource).unwrap();
    let mut t = Trajectory::hold(&[0.25; NJ]);
    t.traj_id = 7;
    p.publish(&mut t).unwrap();
    let b = Bus::new(&run, "b").unwrap();
    let mut s = b.subscriber::<Trajectory>().unwrap();
    p.update_connections().unwrap();
    let mut got = Trajectory::hold(&[0.0; NJ]);
    assert!(s.latest(&mut got, &lim()).unwrap());
    assert_eq!(got.traj_id, 7);
    assert_eq!(got.sample(1.0).p, [0.25; NJ]);
}

#[test]
fn two_runs_never_see_each_other() {
    let r1 = run_id("iso1");
    let r2 = run_id("iso2");
    let _clean = (Leftovers(r1.clone()), Leftovers(r2.clone()));
    let a = Bus::new(&r1, "a").unwrap();
    let b = Bus::new(&r2, "b").unwrap();
    let mut p = a.publisher::<RobotState>(Source::Sim).unwrap();
    let mut s = b.subscriber::<RobotState>().unwrap();
    p.update_connections().unwrap();
    p.publish(&mut state(0.1)).unwrap();
    let mut got = <RobotState as Zeroed>::zeroed();
    assert!(!s.latest(&mut got, &lim()).unwrap());
    assert_eq!(s.received, 0);
    // Node listing is per run too.
    let (alive, _) = Bus::nodes(&run_config(&r1).unwrap()).unwrap();
    let names: Vec<_> = alive.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names, vec!["a"]);
}

#[test]
fn bad_run_ids_are_refused_with_a_reason() {
    let e = run_config("has space").unwrap_err();
    assert!(e.to_string().contains("run id"), "{e}");
    assert!(run_config("").is_err());
}

#[test]
fn a_finished_run_leaves_no_files() {
    let run = run_id("leftover");
    {
        let a = Bus::new(&run, "a").unwrap();
        let b = Bus::new(&run, "b").unwrap();
        let mut p = a.publisher::<RobotState>(Source::Sim).unwrap();
        let _s = b.subscriber::<RobotState>().unwrap();
        p.update_connections().unwrap();
        p.publish(&mut state(0.2)).unwrap();
    }
    // iceoryx2 keeps its per-prefix management file after the last node is gone.
    let before = shm_files(&run);
    assert!(before >= 1, "expected iceoryx2's management file of the run");
    let removed = remove_run_leftovers(&run);
    assert_eq!(removed, before);
    assert_eq!(shm_files(&run), 0);
}

#[test]
fn a_late_reader_keeps_16_observation_frames_and_counts_the_lost_ones() {
    let run = run_id("lost");
    let _clean = Leftovers(run.clone());
    let a = Bus::new(&run, "a").unwrap();
    let mut p = a.publisher::<DebrisObservation>(Source::Sim).unwrap();
    let mut s = a.subscriber::<DebrisObservation>().unwrap();
    p.update_connections().unwrap();
    let mut frame = <DebrisObservation as Zeroed>::zeroed();
    let mut seqs = Vec::new();
    p.publish(&mut frame).unwrap();
    s.for_each_checked(|_| Ok(()), |f| seqs.push(f.header.seq)).unwrap();
    assert_eq!((seqs.as_slice(), s.lost), (&[0u64][..], 0));
    // The reader is late by 20 frames: the oldest 4 are overwritten, and counted.
    for _ in 0..20 {
        p.publish(&mut frame).unwrap();
    }
    seqs.clear();
    s.for_each_checked(|_| Ok(()), |f| seqs.push(f.header.seq)).unwrap();
    assert_eq!(seqs, (5..=20).collect::<Vec<u64>>());
    assert_eq!((s.received, s.lost), (17, 4));
    // State topics keep only 4 (the tracker polls the newest); gaps are counted the same way.
    let mut ps = a.publisher::<RobotState>(Source::Sim).unwrap();
    let mut ss = a.subscriber::<RobotState>().unwrap();
    ps.update_connections().unwrap();
    let mut got = <RobotState as Zeroed>::zeroed();
    ps.publish(&mut state(0.0)).unwrap();
    assert!(ss.latest(&mut got, &lim()).unwrap());
    for i in 1..=10 {
        ps.publish(&mut state(i as f64 * 0.1)).unwrap();
    }
    assert!(ss.latest(&mut got, &lim()).unwrap());
    assert_eq!((got.header.seq, ss.received, ss.lost), (10, 5, 6));
}

#[test]
fn a_publisher_lock_follows_the_runs_own_state_publisher_and_the_next_when_it_leaves() {
    use dkrrt_msg::bus::PublisherLock;
    let run = run_id("lock");
    let _clean = Leftovers(run.clone());
    let reader = Bus::new(&run, "planner").unwrap();
    let mut locked = reader.subscriber::<RobotState>().unwrap();
    let mut plain = reader.subscriber::<RobotState>().unwrap();
    let mut lock = PublisherLock::default();
    let (ours_bus, rogue_bus) = (Bus::new(&run, "sim").unwrap(), Bus::new(&run, "rogue").unwrap());
    let mut ours = ours_bus.publisher::<RobotState>(Source::Sim).unwrap();
    let mut rogue = rogue_bus.publisher::<RobotState>(Source::Sim).unwrap();
    ours.update_connections().unwrap();
    rogue.update_connections().unwrap();
    let mut got = <RobotState as Zeroed>::zeroed();
    // The first publisher heard is followed.
    ours.publish(&mut state(0.1)).unwrap();
    assert!(lock.latest(&reader, &mut locked, &mut got, &lim()).unwrap());
    assert_eq!(got.q[0], 0.1);
    // A rogue's newer states are dropped and counted; a plain reader would take them.
    ours.publish(&mut state(0.2)).unwrap();
    rogue.publish(&mut state(0.8)).unwrap();
    assert!(lock.latest(&reader, &mut locked, &mut got, &lim()).unwrap());
    assert_eq!((got.q[0], locked.foreign), (0.2, 1));
    let mut other = <RobotState as Zeroed>::zeroed();
    assert!(plain.latest(&mut other, &lim()).unwrap());
    assert_eq!(other.q[0], 0.8, "without the lock the newest sample, the rogue's, is read");
    rogue.publish(&mut state(0.9)).unwrap();
    assert!(!lock.latest(&reader, &mut locked, &mut got, &lim()).unwrap());
    assert_eq!(got.q[0], 0.2);
    // Ours leaves the service (a restarted driver): the next publisher heard takes over.
    drop(ours);
    drop(ours_bus);
    rogue.update_connections().unwrap();
    rogue.publish(&mut state(0.7)).unwrap();
    let _ = lock.latest(&reader, &mut locked, &mut got, &lim()).unwrap();
    rogue.publish(&mut state(0.6)).unwrap();
    assert!(lock.latest(&reader, &mut locked, &mut got, &lim()).unwrap());
    assert_eq!(got.q[0], 0.6);
}

/// A forecast of `count` tracks of `steps` steps, each value telling where it came from.
fn forecast(count: usize, steps: usize, tag: f64) -> Box<DebrisForecast> {
    let mut f = Box::new(<DebrisForecast as Zeroed>::zeroed());
    (f.count, f.steps, f.dt_s) = (count as u32, steps as u32, 0.1);
    for (i, tr) in f.tracks.iter_mut().enumerate().take(count) {
        (tr.id, tr.bounding_radius, tr.shape) = (i as u32, 0.2, DebrisShape::sphere(0.2));
        for (k, st) in tr.steps.iter_mut().enumerate().take(steps) {
            *st = ForecastStep {
                p: [tag + i as f64, k as f64 * 0.01, 0.0],
                q: [1.0, 0.0, 0.0, 0.0],
                sigma_m: 0.05,
                sigma_pos_m: 0.05,
            };
        }
    }
    f
}

#[test]
fn the_bus_moves_the_used_part_of_a_message_and_the_reader_sees_all_of_it() {
    let run = run_id("used");
    let _clean = Leftovers(run.clone());
    let a = Bus::new(&run, "a").unwrap();
    let b = Bus::new(&run, "b").unwrap();
    let mut p = a.publisher::<DebrisForecast>(Source::Predictor).unwrap();
    let mut s = b.subscriber::<DebrisForecast>().unwrap();
    p.update_connections().unwrap();
    // A full forecast first (every track and step of the samples' memory written), then
    // smaller ones: each is read back whole, wherever its samples' tails stood.
    let mut got = forecast(MAX_DEBRIS, FORECAST_STEPS, 100.0);
    for (count, steps, tag) in
        [(MAX_DEBRIS, FORECAST_STEPS, 1.0), (3, 12, 2.0), (5, 40, 3.0), (1, 1, 4.0), (0, 7, 5.0)]
    {
        let mut f = forecast(count, steps, tag);
        // What lies beyond the counts of the sent message is not part of it.
        if count < MAX_DEBRIS {
            f.tracks[count].steps[0].p = [f64::NAN; 3];
        }
        if steps < FORECAST_STEPS && count > 0 {
            f.tracks[0].steps[steps].sigma_m = f64::INFINITY;
        }
        p.publish(&mut f).unwrap();
        assert!(s.latest(&mut got, &lim()).unwrap(), "{count} tracks × {steps} steps");
        assert_eq!((got.count, got.steps, got.header.seq), (count as u32, steps as u32, f.header.seq));
        for i in 0..count {
            assert_eq!(got.tracks[i].id, i as u32);
            assert_eq!(got.tracks[i].shape, DebrisShape::sphere(0.2));
            assert_eq!(
                got.tracks[i].steps[..steps],
                f.tracks[i].steps[..steps],
                "{count} × {steps}: track {i}"
            );
        }
        assert_eq!(f.used_bytes(), 56 + count * (72 + 72 * steps));
    }
    // Nothing beyond the counts was copied: the reader's tails hold the last message that
    // used them (track 10: the first, full one; track 0's step 1: the 5 × 40 one).
    assert_eq!(got.tracks[10].steps[0].p[0], 1.0 + 10.0);
    assert_eq!(got.tracks[0].steps[1].p[0], 3.0);
    assert_eq!(s.rejected, 0);

    // Trajectories: each joint's own segment count.
    let mut tp = a.publisher::<Trajectory>(Source::TrajectorySource).unwrap();
    let mut ts = b.subscriber::<Trajectory>().unwrap();
    tp.update_connections().unwrap();
    let mut t = Trajectory::hold(&[0.25; NJ]);
    t.n_seg = [1, 2, 3, 1, 5, 1];
    for j in 0..NJ {
        for k in 0..MAX_SEGMENTS {
            t.seg[j][k] =
                JerkSegment { t0: k as f64 * 0.1, p: 0.25 + j as f64 * 0.01, v: 0.0, a: 0.0, j: 0.0 };
        }
    }
    t.duration_s = 1.0;
    let mut gt = <Trajectory as Zeroed>::zeroed();
    tp.publish(&mut t).unwrap();
    assert!(ts.latest(&mut gt, &lim()).unwrap());
    for j in 0..NJ {
        let n = t.n_seg[j] as usize;
        assert_eq!(gt.seg[j][..n], t.seg[j][..n]);
        assert_eq!(gt.seg[j][n].t0, 0.0, "joint {j}: segment {n} is beyond its count");
        assert_eq!(gt.sample(0.7).p[j], t.sample(0.7).p[j]);
    }
    assert_eq!((gt.duration_s, gt.n_seg), (1.0, t.n_seg));
    assert_eq!(t.used_bytes(), 80 + 13 * 40);

    // Observation frames: `count` items.
    let mut op = a.publisher::<DebrisObservation>(Source::Sim).unwrap();
    let mut os = b.subscriber::<DebrisObservation>().unwrap();
    op.update_connections().unwrap();
    let mut frame = <DebrisObservation as Zeroed>::zeroed();
    frame.count = 2;
    for (i, it) in frame.items.iter_mut().enumerate() {
        it.id = 10 + i as u32;
    }
    op.publish(&mut frame).unwrap();
    let mut ids = Vec::new();
    os.for_each_checked(|_| Ok(()), |f| ids.extend(f.items[..f.count as usize].iter().map(|o| o.id)))
        .unwrap();
    assert_eq!(ids, [10, 11]);
}
