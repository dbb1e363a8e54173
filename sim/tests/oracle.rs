//! The oracle's recorded truth is the simulator's future, bit for bit at the kept samples,
//! events included; its forecasts carry no uncertainty and know a fragment before it splits.

use dkrrt_config::Scenario;
use dkrrt_model::ArmModel;
use dkrrt_msg::{ContractLimits, DebrisForecast, Validate, Zeroed};
use dkrrt_sim::debris::DebrisSide;

#[test]
fn the_truth_table_is_the_simulated_future_and_knows_the_split() {
    let mut sc = Scenario::default_scenario();
    sc.episode = None;
    sc.debris.scene = "tumbling-rods".into(); // an impulse at 10 s, a split at 15 s
    let base = [0.3, -0.2, 0.1];
    sc.debris.base_lvlh = base;
    let dt = 1e-3;
    let mut side = DebrisSide::new(&sc, &ArmModel::default_arm()).unwrap();
    let table = side.truth_table(dt, 17_000, 10);
    assert!((table.span_s() - 17.0).abs() < 1e-9);
    let mut checked = 0;
    for tick in 1..=17_000u64 {
        side.step(dt);
        if tick % 500 != 0 {
            continue;
        }
        let t = tick as f64 * dt;
        for d in side.world().debris() {
            let (p, q) = table.pose(d.id, t).unwrap();
            let qq = d.state.q.quaternion();
            let dp = (p[0] - d.state.p.x).abs() + (p[1] - d.state.p.y).abs() + (p[2] - d.state.p.z).abs();
            let dq = (q[0] - qq.w).abs() + (q[1] - qq.i).abs() + (q[2] - qq.j).abs() + (q[3] - qq.k).abs();
            assert!(dp < 1e-12 && dq < 1e-12, "id {} at {t} s: {dp} m, {dq}", d.id);
            checked += 1;
        }
    }
    assert!(side.world().events_fired() == 2 && checked > 200, "{checked}");

    // A forecast from 12 s: every object with the true future, zero bound, the fragment
    // (id 100, split off at 15 s) already there, validated by the contract.
    let mut msg = Box::new(<DebrisForecast as Zeroed>::zeroed());
    let n = table.forecast_into(12.0, 40, 0.1, &mut msg);
    let ids: Vec<u32> = msg.tracks[..n].iter().map(|t| t.id).collect();
    assert!(ids.contains(&100) && ids.contains(&6), "{ids:?}");
    assert_eq!(ids.iter().filter(|&&i| i == 100).count(), 1);
    for tr in &msg.tracks[..n] {
        for (k, st) in tr.steps[..40].iter().enumerate() {
            assert_eq!((st.sigma_m, st.sigma_pos_m), (0.0, 0.0));
            let (p, _) = table.pose(tr.id, 12.0 + (k + 1) as f64 * 0.1).unwrap();
            assert!((st.p[0] - (p[0] - base[0])).abs() < 1e-12, "base frame");
        }
    }
    assert_eq!((msg.steps, msg.t0_ns), (40, 12_000_000_000));
    msg.validate(&ContractLimits::symmetric(1.0, 1.0, 1.0)).unwrap();
    // From 16 s the split is in the past: the fragment exists now.
    let n = table.forecast_into(16.0, 10, 0.1, &mut msg);
    assert!(msg.tracks[..n].iter().any(|t| t.id == 100));
}
