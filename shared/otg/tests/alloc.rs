//! calculate / sample / segment access allocate nothing.

use dkrrt_otg::{KinState, Limits, Options, Trajectory};
use dkrrt_rt::alloc_count::{count, CountingAlloc};

#[global_allocator]
static ALLOC: CountingAlloc = CountingAlloc;

#[test]
fn calculate_and_sample_allocate_nothing() {
    let lim = Limits { v_max: [1.0; 7], a_max: [2.0; 7], j_max: [5.0; 7] };
    let s = KinState { p: [0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7], v: [0.0; 7], a: [0.0; 7] };
    let t = KinState::rest([1.0, -1.0, 0.5, 2.0, -0.3, 0.0, 3.0]);
    let o = Options::default();
    let (r, st) = count(|| {
        let tr = Trajectory::calculate(&s, &t, &lim, &o).unwrap();
        let mut acc = 0.0;
        for k in 0..100 {
            acc += tr.at(tr.duration() * k as f64 / 100.0).p[3];
        }
        acc += tr.position_extrema()[0].max;
        acc += tr.joint_segments(2).len() as f64;
        let moving = KinState { p: [0.0; 7], v: [0.5; 7], a: [1.0; 7] };
        let stop = Trajectory::calculate_velocity(&moving, &[0.0; 7], &[0.0; 7], &lim, &o).unwrap();
        acc + stop.duration()
    });
    assert!(r.is_finite());
    assert_eq!(st.allocs, 0, "{st:?}");
    assert_eq!(st.reallocs, 0, "{st:?}");
}

#[test]
fn online_update_and_waypoints_allocate_nothing() {
    use dkrrt_otg::Otg;
    let lim = Limits { v_max: [1.0; 6], a_max: [2.0; 6], j_max: [5.0; 6] };
    let mut otg = Otg::new(lim, Options::default(), 0.001).unwrap();
    let target = KinState::rest([1.0, -1.0, 0.5, 2.0, -0.3, 0.0]);
    let wps = [[0.5, -0.5, 0.3, 1.0, -0.1, 0.1], [0.8, -0.8, 0.4, 1.5, -0.2, 0.0]];
    let (r, st) = count(|| {
        let mut s = KinState::rest([0.0; 6]);
        for _ in 0..200 {
            s = otg.update(&s, &target).unwrap().state;
        }
        let w = Trajectory::calculate_waypoints(
            &KinState::rest([0.0; 6]),
            &wps,
            &target,
            &lim,
            &Options::default(),
        )
        .unwrap();
        s.p[0] + w.duration()
    });
    assert!(r.is_finite());
    assert_eq!(st.allocs, 0, "{st:?}");
}
