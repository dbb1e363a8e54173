//! The wire format: round trips, sizes, every corruption refused and named, no panics on any
//! input, and no allocation.

use dkrrt_udp::*;
use proptest::prelude::*;

#[global_allocator]
static ALLOC: dkrrt_rt::alloc_count::CountingAlloc = dkrrt_rt::alloc_count::CountingAlloc;

fn state() -> StatePacket {
    StatePacket {
        seq: 41,
        arm_time_ns: 1_234_567_890_123,
        q: [0.1, -0.2, 0.3, -0.4, 0.5, -0.6],
        qd: [0.01, 0.02, -0.03, 0.04, -0.05, 0.06],
        tau: [1.5, -2.5, 3.5, -4.5, 5.5, -6.5],
        status: status::BRAKES | status::ABORTED,
        missed: 20,
        last_command_seq: 17,
        abort_after: 20,
    }
}

fn command() -> CommandPacket {
    CommandPacket {
        seq: 9,
        state_seq: 41,
        mode: Mode::Torque,
        tau: [10.0, -20.0, 30.0, -4.0, 5.0, -6.0],
        q: [0.0; 6],
        qd: [0.0; 6],
    }
}

#[test]
fn packets_round_trip_with_the_documented_sizes() {
    // docs/udp-protocol.md: 184 and 168 bytes.
    assert_eq!((STATE_LEN, COMMAND_LEN), (184, 168));
    let mut b = [0u8; STATE_LEN];
    assert_eq!(state().encode(&mut b), STATE_LEN);
    assert_eq!(StatePacket::decode(&b), Ok(state()));
    assert_eq!(kind_of(&b), Some(Kind::State));
    assert_eq!(&b[..4], b"DKRA");
    let mut c = [0u8; COMMAND_LEN];
    for mode in [Mode::Hold, Mode::Torque, Mode::Servo] {
        let cmd = CommandPacket { mode, ..command() };
        assert_eq!(cmd.encode(&mut c), COMMAND_LEN);
        assert_eq!(CommandPacket::decode(&c), Ok(cmd));
    }
    assert_eq!(kind_of(&c), Some(Kind::Command));
    // Fields sit where the document says (little-endian): seq at 8, the state's clock at 12.
    assert_eq!(u32::from_le_bytes(b[8..12].try_into().unwrap()), 41);
    assert_eq!(u64::from_le_bytes(b[12..20].try_into().unwrap()), 1_234_567_890_123);
    assert_eq!(f64::from_le_bytes(b[20..28].try_into().unwrap()), 0.1);
    assert_eq!(u32::from_le_bytes(c[12..16].try_into().unwrap()), 41);
    assert_eq!(u16::from_le_bytes(c[16..18].try_into().unwrap()), Mode::Servo as u16);
}

#[test]
fn every_single_bit_flip_is_caught() {
    let mut b = [0u8; STATE_LEN];
    state().encode(&mut b);
    for i in 0..STATE_LEN * 8 {
        let mut d = b;
        d[i / 8] ^= 1 << (i % 8);
        assert!(
            matches!(StatePacket::decode(&d), Err(PacketError::Checksum { .. })),
            "bit {i}: {:?}",
            StatePacket::decode(&d)
        );
    }
}

#[test]
fn wrong_packets_are_refused_naming_what_is_wrong() {
    let mut b = [0u8; STATE_LEN];
    state().encode(&mut b);
    assert_eq!(StatePacket::decode(&b[..100]), Err(PacketError::Length { got: 100, want: STATE_LEN }));
    let mut c = [0u8; COMMAND_LEN];
    command().encode(&mut c);
    // A command is not a state (and not of a state's length).
    assert!(matches!(StatePacket::decode(&c), Err(PacketError::Length { .. })));
    // Re-sealed with a valid checksum, each header field is still checked.
    let reseal = |mut d: [u8; STATE_LEN]| {
        let crc = crc(&d[..STATE_LEN - 4]);
        d[STATE_LEN - 4..].copy_from_slice(&crc.to_le_bytes());
        d
    };
    let mut d = b;
    d[0] = b'X';
    assert!(matches!(StatePacket::decode(&reseal(d)), Err(PacketError::Magic(_))));
    let mut d = b;
    d[4] = 2;
    assert_eq!(StatePacket::decode(&reseal(d)), Err(PacketError::Version(2)));
    let mut d = b;
    d[6] = 2;
    assert_eq!(StatePacket::decode(&reseal(d)), Err(PacketError::Kind(2)));
    let mut d = b;
    d[20..28].copy_from_slice(&f64::NAN.to_le_bytes());
    assert_eq!(StatePacket::decode(&reseal(d)), Err(PacketError::NonFinite("q")));
    let mut d = b;
    d[20 + 2 * 48..28 + 2 * 48].copy_from_slice(&f64::INFINITY.to_le_bytes());
    assert_eq!(StatePacket::decode(&reseal(d)), Err(PacketError::NonFinite("tau")));
    // An unknown mode.
    let mut e = c;
    e[16] = 7;
    let crc = crc(&e[..COMMAND_LEN - 4]);
    e[COMMAND_LEN - 4..].copy_from_slice(&crc.to_le_bytes());
    assert_eq!(CommandPacket::decode(&e), Err(PacketError::Mode(7)));
    assert!(PacketError::Mode(7).to_string().contains("mode 7"));
}

/// CRC-32/ISO-HDLC written out bit by bit (the check value of "123456789" is 0xCBF43926): the
/// oracle for the crate's checksum.
fn crc(data: &[u8]) -> u32 {
    let mut c = 0xFFFF_FFFFu32;
    for &b in data {
        c ^= b as u32;
        for _ in 0..8 {
            c = if c & 1 == 1 { (c >> 1) ^ 0xEDB8_8320 } else { c >> 1 };
        }
    }
    !c
}

#[test]
fn the_checksum_is_crc32_iso_hdlc() {
    assert_eq!(crc(b"123456789"), 0xCBF4_3926);
    let mut b = [0u8; STATE_LEN];
    state().encode(&mut b);
    assert_eq!(u32::from_le_bytes(b[STATE_LEN - 4..].try_into().unwrap()), crc(&b[..STATE_LEN - 4]));
}

#[test]
fn encode_and_decode_allocate_nothing() {
    let mut b = [0u8; STATE_LEN];
    let mut c = [0u8; COMMAND_LEN];
    let (s, k) = (state(), command());
    let mut link = dkrrt_udp::link::SeqTracker::new();
    let ((), st) = dkrrt_rt::alloc_count::count(|| {
        for i in 0..1000u32 {
            std::hint::black_box(link.on_packet(i.wrapping_mul(7) % 50));
            s.encode(&mut b);
            k.encode(&mut c);
            std::hint::black_box(StatePacket::decode(&b).unwrap());
            std::hint::black_box(CommandPacket::decode(&c).unwrap());
            std::hint::black_box(StatePacket::decode(&c[..10]).unwrap_err());
        }
    });
    assert_eq!((st.allocs, st.reallocs), (0, 0));
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, ..ProptestConfig::default() })]

    #[test]
    fn any_datagram_decodes_or_is_refused_without_panic(bytes in proptest::collection::vec(any::<u8>(), 0..260)) {
        let _ = StatePacket::decode(&bytes);
        let _ = CommandPacket::decode(&bytes);
        let _ = kind_of(&bytes);
    }

    #[test]
    fn finite_states_round_trip(seq in any::<u32>(), t in any::<u64>(), q in proptest::array::uniform6(-1e6f64..1e6), st in any::<u32>()) {
        let p = StatePacket { seq, arm_time_ns: t, q, qd: q, tau: q, status: st, missed: st, last_command_seq: seq, abort_after: 20 };
        let mut b = [0u8; STATE_LEN];
        p.encode(&mut b);
        prop_assert_eq!(StatePacket::decode(&b), Ok(p));
    }
}
