//! Waiting for a socket with a sub-millisecond timeout (`ppoll(2)`; `poll(2)` has ms resolution).

use std::os::fd::AsRawFd;

/// Waits until `fd` is readable or `timeout_ns` has passed (or a signal arrives); returns true
/// if it is readable. A zero timeout only checks.
pub fn wait_readable(fd: &impl AsRawFd, timeout_ns: u64) -> bool {
    let mut p = libc::pollfd { fd: fd.as_raw_fd(), events: libc::POLLIN, revents: 0 };
    let ts = libc::timespec {
        tv_sec: (timeout_ns / 1_000_000_000) as libc::time_t,
        tv_nsec: (timeout_ns % 1_000_000_000) as libc::c_long,
    };
    // SAFETY: one valid pollfd, a valid timespec, no signal mask change.
    let n = unsafe { libc::ppoll(&mut p, 1, &ts, std::ptr::null()) };
    n > 0 && p.revents & libc::POLLIN != 0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_datagram_wakes_the_wait_and_silence_times_out() {
        let a = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
        let b = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
        assert!(!wait_readable(&a, 1_000_000));
        b.send_to(b"x", a.local_addr().unwrap()).unwrap();
        assert!(wait_readable(&a, 1_000_000_000));
    }
}
