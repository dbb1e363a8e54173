//! The driver core and the emulated arm over the emulated network, without sockets or IPC: a
//! hold loop at rest through delay, jitter, loss, duplication and reordering; the driver's
//! counts agree with what the network did; no allocation in the loop.

use dkrrt_config::Scenario;
use dkrrt_emulator::net::{DelayLine, Impairment, MAX_DATAGRAM};
use dkrrt_emulator::{ArmEmulator, EmulatorConfig};
use dkrrt_model::ArmModel;
use dkrrt_sim::plant::PlantConfig;
use dkrrt_udp::{Mode, COMMAND_LEN, NJ, STATE_LEN};
use dkrrt_udp_driver::core::{DriverCore, Dropped};

#[global_allocator]
static ALLOC: dkrrt_rt::alloc_count::CountingAlloc = dkrrt_rt::alloc_count::CountingAlloc;

#[test]
fn through_a_lossy_network_the_driver_counts_what_the_network_did_and_allocates_nothing() {
    let sc = Scenario::default_scenario();
    let period = sc.period_ns();
    let mut arm = ArmEmulator::new(
        ArmModel::default_arm(),
        PlantConfig::from_scenario(&sc),
        &sc.sim.initial_q,
        EmulatorConfig::new(period),
    );
    let imp = Impairment {
        delay_ns: 300_000,
        jitter_ns: 200_000,
        loss: 0.02,
        duplicate: 0.01,
        reorder: 0.01,
        reorder_ns: 1_500_000,
    };
    let (mut up, mut down) = (DelayLine::new(imp, 1), DelayLine::new(imp, 2));
    let mut drv = DriverCore::new();
    let (mut sb, mut cb, mut buf) = ([0u8; STATE_LEN], [0u8; COMMAND_LEN], [0u8; MAX_DATAGRAM]);
    let (mut bus_seq, mut published, mut late, mut dup) = (0u64, 0u64, 0u64, 0u64);
    let q0 = sc.sim.initial_q;
    let mut run = |ticks: u64, t0: u64| {
        for k in 0..ticks {
            let t = t0 + k * period;
            if k + t0 / period > 0 {
                arm.step();
            }
            let n = arm.state(&mut sb);
            up.push(t, &sb[..n]);
            // The driver's side, every 50 µs of the tick: states in, answers out at once.
            for sub in 0..20u64 {
                let now = t + sub * 50_000;
                while let Some(n) = up.pop_due(now, &mut buf) {
                    match drv.on_datagram(now, &buf[..n]) {
                        Ok(s) => {
                            drv.published(bus_seq, s.arm_seq);
                            published += 1;
                            // Hold where it is: servo to the start, at rest.
                            let len = drv
                                .command(now, bus_seq, Mode::Servo, &[0.0; NJ], &q0, &[0.0; NJ], &mut cb)
                                .unwrap();
                            down.push(now, &cb[..len]);
                            bus_seq += 1;
                        }
                        Err(Dropped::Late) => late += 1,
                        Err(Dropped::Duplicate) => dup += 1,
                        Err(e) => panic!("{e:?}"),
                    }
                }
                while let Some(n) = down.pop_due(now, &mut buf) {
                    let _ = arm.receive(&buf[..n]);
                }
            }
        }
    };
    run(500, 0);
    let (_, a) = dkrrt_rt::alloc_count::count(|| run(5000, 500 * period));
    assert_eq!(a.allocs, 0, "{a:?}");
    let st = drv.stats;
    // Every state the network delivered is counted once: used, late or duplicate.
    assert_eq!(st.states.received, up.stats.delivered);
    assert_eq!(published + late + dup, up.stats.delivered);
    assert_eq!(st.states.duplicates, dup);
    assert!(up.stats.lost > 50 && st.states.lost >= up.stats.lost - late, "{:?} {st:?}", up.stats);
    assert_eq!(st.invalid, 0);
    // 20 missed commands in a row at 2 % loss: essentially never; the arm held on its servo.
    assert_eq!(arm.stats.aborts, 0);
    let (q, qd) = arm.plant().true_state();
    let dq = q.iter().zip(&q0).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
    assert!(dq < 1e-6 && qd.amax() < 1e-6, "held: {dq} {}", qd.amax());
    assert!(drv.command_echo_us().count > 1000);
}
