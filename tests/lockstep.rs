//! The in-process lockstep evaluation: deterministic and accurate.

use dkrrt_config::Scenario;

#[test]
fn lockstep_reaches_the_goal_and_is_deterministic() {
    let sc = Scenario::default_scenario();
    let a = dkrrt::lockstep::run(&sc).unwrap();
    let b = dkrrt::lockstep::run(&sc).unwrap();
    assert_eq!(a.final_q, b.final_q, "same scenario, same result");
    assert_eq!(a.tracking_error_rad_rms, b.tracking_error_rad_rms);
    assert!(a.tracking_error_rad_rms < 1e-3, "{}", a.tracking_error_rad_rms);
    assert!(a.final_error_rad < 1e-6, "{}", a.final_error_rad);
    assert_eq!(a.safe_hold_entries, 0);
    assert!(a.trajectory_duration_s > 1.0 && a.trajectory_duration_s < sc.run.duration_s);
}

#[test]
fn lockstep_with_noise_and_delay_still_tracks() {
    let mut sc = Scenario::default_scenario();
    sc.sim.noise_q_std = 1e-5;
    sc.sim.noise_qd_std = 1e-4;
    sc.sim.delay_ticks = 2;
    let r = dkrrt::lockstep::run(&sc).unwrap();
    assert!(r.tracking_error_rad_rms < 1e-3, "{}", r.tracking_error_rad_rms);
    assert!(r.final_error_rad < 1e-3, "{}", r.final_error_rad);
}
