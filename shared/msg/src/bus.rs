//! iceoryx2 wiring shared by every process: per-run isolation, one service
//! per payload type with identical QoS everywhere, and thin publisher /
//! subscriber wrappers that stamp headers and validate what arrives.
//!
//! Isolation: every run has a run id; all iceoryx2 resources of a run carry
//! the file prefix `dkrrt_<run>_`, so two runs on one machine never see each
//! other (nodes, services and shared memory are all distinct).

use core::fmt::Debug;
use core::mem::MaybeUninit;

use iceoryx2::config::Config;
use iceoryx2::node::{Node, NodeBuilder, NodeState, NodeView};
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::port::update_connections::UpdateConnections;
use iceoryx2::prelude::{
    ipc, CallbackProgression, FileName, NodeName, SemanticString, ServiceName, SignalHandlingMode,
    ZeroCopySend,
};

use crate::types::*;
use crate::used::UsedPart;
use crate::validate::{ContractLimits, Validate, ValidationError};

/// An error while setting up or using the bus; says what was attempted.
#[derive(Debug, thiserror::Error)]
#[error("{what}: {detail}")]
pub struct BusError {
    pub what: String,
    pub detail: String,
}

fn err(what: impl Into<String>, detail: impl Debug) -> BusError {
    BusError { what: what.into(), detail: format!("{detail:?}") }
}

/// An error whose detail is already a sentence (shown as is, not debug-quoted).
fn err_text(what: impl Into<String>, detail: String) -> BusError {
    BusError { what: what.into(), detail }
}

/// A payload type of the contract, with the one service that carries it.
pub trait Topic: Debug + Copy + ZeroCopySend + Validate + Zeroed + UsedPart + 'static {
    /// iceoryx2 service name.
    const SERVICE: &'static str;
    /// Samples a subscriber buffers before the oldest is overwritten.
    const BUFFER: usize = SUBSCRIBER_BUFFER;
    fn header(&self) -> &Header;
    fn header_mut(&mut self) -> &mut Header;
}

macro_rules! topic {
    ($t:ty, $name:expr) => {
        topic!($t, $name, SUBSCRIBER_BUFFER);
    };
    ($t:ty, $name:expr, $buffer:expr) => {
        impl Topic for $t {
            const SERVICE: &'static str = $name;
            const BUFFER: usize = $buffer;
            fn header(&self) -> &Header {
                &self.header
            }
            fn header_mut(&mut self) -> &mut Header {
                &mut self.header
            }
        }
    };
}
topic!(RobotState, "dkrrt/robot_state");
topic!(TorqueCommand, "dkrrt/torque_command");
topic!(Trajectory, "dkrrt/trajectory");
topic!(Goal, "dkrrt/goal");
topic!(Heartbeat, "dkrrt/health");
// Every observation frame matters (the predictor filters each one): 16 frames = 160–530 ms of
// slack at 30–100 Hz before a late reader loses one (counted in `Sub::lost`).
topic!(DebrisObservation, "dkrrt/debris_observation", OBSERVATION_BUFFER);
topic!(DebrisForecast, "dkrrt/debris_forecast");
topic!(PlanStatus, "dkrrt/plan_status");
topic!(PredictorProgress, "dkrrt/predictor_progress");
// Every frame of a capture matters too: a rig publishes one per face (six) at once, and the
// predictor reads them every 20 ms; 16 frames hold two captures and a late read.
topic!(DepthImage, "dkrrt/depth_image", DEPTH_BUFFER);

/// QoS shared by all services (open_or_create needs the same values everywhere).
pub const MAX_PUBLISHERS: usize = 8;
pub const MAX_SUBSCRIBERS: usize = 8;
pub const MAX_NODES: usize = 16;
/// Samples a subscriber buffers; on overflow the oldest is dropped (we poll the latest).
pub const SUBSCRIBER_BUFFER: usize = 4;
/// Subscriber buffer of the debris observation stream.
pub const OBSERVATION_BUFFER: usize = 16;
/// Subscriber buffer of the depth camera's frames (a cube rig sends six per capture).
pub const DEPTH_BUFFER: usize = 16;
/// Late subscribers receive the last sample (the active trajectory or goal).
pub const HISTORY: usize = 1;

/// Longest run id (iceoryx2's file names must hold the prefix `dkrrt_<run>_` plus its own
/// 40-hex-digit service hashes and suffixes).
pub const MAX_RUN_ID: usize = 64;

/// Checks a run id: 1..=[`MAX_RUN_ID`] letters, digits and '-', starting with a letter or digit
/// (so it can never be read as an option).
pub fn check_run_id(run: &str) -> Result<(), BusError> {
    let shown: String = run.chars().take(80).flat_map(char::escape_default).collect();
    if run.is_empty() || run.len() > MAX_RUN_ID {
        return Err(err_text("run id", format!("\"{shown}\" must be 1 to {MAX_RUN_ID} characters long")));
    }
    if !run.chars().all(|c| c.is_ascii_alphanumeric() || c == '-')
        || !run.starts_with(|c: char| c.is_ascii_alphanumeric())
    {
        return Err(err_text(
            "run id",
            format!("\"{shown}\": use letters, digits and '-', starting with a letter or digit"),
        ));
    }
    Ok(())
}

/// The iceoryx2 root directory of this user: `/tmp/dkrrt-iceoryx2-<uid>/`, created owner-only
/// (0700). iceoryx2's shared default (`/tmp/iceoryx2/`) belongs to whoever made it first; this
/// one is checked to be a real directory (not a symlink) owned by us and closed to others.
pub fn private_root() -> Result<std::path::PathBuf, BusError> {
    use std::os::unix::fs::{DirBuilderExt, MetadataExt, PermissionsExt};
    // SAFETY: getuid(2) cannot fail.
    let uid = unsafe { libc::getuid() };
    let dir = std::env::temp_dir().join(format!("dkrrt-iceoryx2-{uid}"));
    match std::fs::DirBuilder::new().mode(0o700).create(&dir) {
        Ok(()) => {}
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {}
        Err(e) => return Err(err(format!("create {}", dir.display()), e)),
    }
    let m = std::fs::symlink_metadata(&dir).map_err(|e| err(format!("inspect {}", dir.display()), e))?;
    if !m.file_type().is_dir() || m.uid() != uid {
        return Err(err_text(
            format!("iceoryx2 root {}", dir.display()),
            "is not a directory of this user (another user may have planted it): remove it".to_string(),
        ));
    }
    if m.permissions().mode() & 0o077 != 0 {
        std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o700))
            .map_err(|e| err(format!("chmod 700 {}", dir.display()), e))?;
    }
    Ok(dir)
}

/// The iceoryx2 config of run `run`: its own file prefix, under this user's private root.
pub fn run_config(run: &str) -> Result<Config, BusError> {
    check_run_id(run)?;
    let mut cfg = Config::default();
    let prefix = format!("dkrrt_{run}_");
    cfg.global.prefix = FileName::new(prefix.as_bytes()).map_err(|e| err("run prefix", e))?;
    let root = format!("{}/", private_root()?.display());
    let root = iceoryx2::prelude::Path::new(root.as_bytes()).map_err(|e| err("iceoryx2 root", e))?;
    cfg.global.set_root_path(&root);
    Ok(cfg)
}

/// iceoryx2 0.10 creates its per-prefix management segment in `/dev/shm` world-writable
/// (0666): another user could overwrite it and break later nodes. Makes ours owner-only and
/// refuses a run whose segment belongs to someone else (planted before the run started).
fn protect_shm(run: &str) -> Result<(), BusError> {
    use std::os::unix::fs::{MetadataExt, PermissionsExt};
    // SAFETY: getuid(2) cannot fail.
    let uid = unsafe { libc::getuid() };
    let prefix = format!("dkrrt_{run}_");
    for e in std::fs::read_dir("/dev/shm").into_iter().flatten().flatten() {
        let name = e.file_name().to_string_lossy().to_string();
        if !name.starts_with(&prefix) {
            continue;
        }
        let Ok(m) = std::fs::symlink_metadata(e.path()) else { continue };
        if m.uid() != uid {
            return Err(err_text(
                format!("run {run}"),
                format!("/dev/shm/{name} belongs to another user: refusing to use this run id"),
            ));
        }
        if m.file_type().is_file() && m.permissions().mode() & 0o077 != 0 {
            let _ = std::fs::set_permissions(e.path(), std::fs::Permissions::from_mode(0o600));
        }
    }
    Ok(())
}

/// A process's node on the bus of one run.
pub struct Bus {
    pub node: Node<ipc::Service>,
    pub run: String,
    cfg: Config,
}

impl Bus {
    /// Creates the node `name` for run `run`. Signal handling is left to the
    /// process (see `dkrrt_rt::signals`).
    pub fn new(run: &str, name: &str) -> Result<Bus, BusError> {
        let cfg = run_config(run)?;
        let node_name = NodeName::new(name).map_err(|e| err("node name", e))?;
        let node = NodeBuilder::new()
            .name(&node_name)
            .config(&cfg)
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<ipc::Service>()
            .map_err(|e| err(format!("create node {name} for run {run}"), e))?;
        protect_shm(run)?;
        Ok(Bus { node, run: run.to_string(), cfg })
    }

    fn service<T: Topic>(
        &self,
    ) -> Result<iceoryx2::service::port_factory::publish_subscribe::PortFactory<ipc::Service, T, ()>, BusError>
    {
        let name = ServiceName::new(T::SERVICE).map_err(|e| err("service name", e))?;
        self.node
            .service_builder(&name)
            .publish_subscribe::<T>()
            .max_publishers(MAX_PUBLISHERS)
            .max_subscribers(MAX_SUBSCRIBERS)
            .max_nodes(MAX_NODES)
            .history_size(HISTORY)
            .subscriber_max_buffer_size(T::BUFFER)
            .enable_safe_overflow(true)
            .open_or_create()
            .map_err(|e| err(format!("open service {}", T::SERVICE), e))
    }

    pub fn publisher<T: Topic>(&self, source: Source) -> Result<Pub<T>, BusError> {
        let port = self
            .service::<T>()?
            .publisher_builder()
            .create()
            .map_err(|e| err(format!("publisher on {}", T::SERVICE), e))?;
        Ok(Pub { port, seq: 0, source })
    }

    /// Subscribers connected to `T`'s service now (the service is opened or created).
    pub fn subscriber_count<T: Topic>(&self) -> Result<usize, BusError> {
        use iceoryx2::service::port_factory::PortFactory as _;
        Ok(self.service::<T>()?.dynamic_config().number_of_subscribers())
    }

    /// Publishers connected to `T`'s service now (a dead process's ports count until its
    /// stale resources are removed).
    pub fn publisher_count<T: Topic>(&self) -> Result<usize, BusError> {
        use iceoryx2::service::port_factory::PortFactory as _;
        Ok(self.service::<T>()?.dynamic_config().number_of_publishers())
    }

    /// The unique ids of the publishers connected to `T`'s service now (allocates; for rare
    /// checks such as "is the publisher we followed still there").
    pub fn publisher_ids<T: Topic>(&self) -> Result<Vec<u128>, BusError> {
        use iceoryx2::service::port_factory::PortFactory as _;
        let mut ids = Vec::new();
        self.service::<T>()?.dynamic_config().list_publishers(|p| {
            ids.push(p.publisher_id.value());
            CallbackProgression::Continue
        });
        Ok(ids)
    }

    pub fn subscriber<T: Topic>(&self) -> Result<Sub<T>, BusError> {
        let port = self
            .service::<T>()?
            .subscriber_builder()
            .buffer_size(T::BUFFER)
            .create()
            .map_err(|e| err(format!("subscriber on {}", T::SERVICE), e))?;
        Ok(Sub {
            port,
            received: 0,
            rejected: 0,
            lost: 0,
            last: None,
            last_error: None,
            origin: 0,
            foreign: 0,
        })
    }

    pub fn config(&self) -> &Config {
        &self.cfg
    }

    /// Names of the live nodes of this run, and how many dead ones were found.
    pub fn nodes(cfg: &Config) -> Result<(Vec<(String, u32)>, usize), BusError> {
        let mut alive = Vec::new();
        let mut dead = 0;
        Node::<ipc::Service>::list(cfg, |state| {
            match &state {
                NodeState::Alive(v) => {
                    if let Some(d) = v.details() {
                        alive.push((d.name().as_str().to_string(), d.process_id().value() as u32));
                    }
                }
                NodeState::Dead(_) => dead += 1,
                _ => {}
            }
            CallbackProgression::Continue
        })
        .map_err(|e| err("list nodes", e))?;
        Ok((alive, dead))
    }

    /// Removes the stale resources of dead nodes of the run `cfg` (crashed
    /// processes of earlier runs). Returns how many were cleaned.
    pub fn remove_stale(cfg: &Config) -> Result<usize, BusError> {
        let mut cleaned = 0;
        Node::<ipc::Service>::list(cfg, |state| {
            if let NodeState::Dead(view) = state {
                if view.try_remove_stale_resources().is_ok() {
                    cleaned += 1;
                }
            }
            CallbackProgression::Continue
        })
        .map_err(|e| err("list nodes", e))?;
        Ok(cleaned)
    }
}

/// Removes the small files a finished run leaves in `/dev/shm` (iceoryx2's per-prefix
/// management segment, 16 bytes) once no node of run `run` is alive; call after every
/// `Bus` of the run is dropped. Returns how many files were removed.
pub fn remove_run_leftovers(run: &str) -> usize {
    let prefix = format!("dkrrt_{run}_");
    std::fs::read_dir("/dev/shm")
        .into_iter()
        .flatten()
        .flatten()
        .filter(|e| e.file_name().to_string_lossy().starts_with(&prefix))
        .filter(|e| std::fs::remove_file(e.path()).is_ok())
        .count()
}

/// Publisher of one topic: stamps `seq`, `source` and `mono_ns` into the header.
pub struct Pub<T: Topic> {
    port: Publisher<ipc::Service, T, ()>,
    seq: u64,
    source: Source,
}

impl<T: Topic> Pub<T> {
    /// Publishes `msg` (header `seq`, `source`, `mono_ns` are filled in here;
    /// `stamp_ns` and `flags` are the caller's). The payload's used part
    /// ([`UsedPart`]: all of it but for the counted arrays' unused tails) is copied
    /// once into the loaned shared-memory sample. iceoryx2 0.10 allocates one small
    /// block per loan and frees it on send (counted in the allocation tests).
    pub fn publish(&mut self, msg: &mut T) -> Result<u64, BusError> {
        let h = msg.header_mut();
        h.seq = self.seq;
        h.source = self.source as u32;
        h.mono_ns = dkrrt_rt::clock::mono_ns();
        let mut sample = self.port.loan_uninit().map_err(|e| err(format!("loan on {}", T::SERVICE), e))?;
        let slot: &mut MaybeUninit<T> = sample.payload_mut();
        // SAFETY: `slot` is a properly aligned, writable place for one T.
        unsafe { msg.write_used(slot.as_mut_ptr()) };
        // SAFETY: every field but the counted arrays' tails was written just above. The tails
        // are bytes of the service's shared memory (a file mapping, zero-filled when created,
        // since written only with this type's samples), so every byte holds a value, and every
        // bit pattern is a valid value of the payloads' fields (integers and floats only, as
        // for `Zeroed`); nothing reads them (see `used`).
        let sample = unsafe { sample.assume_init() };
        sample.send().map_err(|e| err(format!("send on {}", T::SERVICE), e))?;
        self.seq += 1;
        Ok(self.seq - 1)
    }

    /// Connects to subscribers that appeared since the last send.
    pub fn update_connections(&self) -> Result<(), BusError> {
        self.port.update_connections().map_err(|e| err(format!("update connections {}", T::SERVICE), e))
    }

    pub fn next_seq(&self) -> u64 {
        self.seq
    }
}

/// Subscriber of one topic that validates every sample and counts rejects.
pub struct Sub<T: Topic> {
    port: Subscriber<ipc::Service, T, ()>,
    /// Samples received (valid or not).
    pub received: u64,
    /// Samples rejected by validation.
    pub rejected: u64,
    /// Samples this subscriber never saw: gaps in a publisher's `header.seq` (its buffer
    /// overflowed while the reader was late). Counted per run of one source; never over-counts.
    pub lost: u64,
    /// Source and `seq` of the last sample received.
    last: Option<(u32, u64)>,
    /// The most recent validation failure.
    pub last_error: Option<ValidationError>,
    /// iceoryx2's unique id of the publisher of the last valid sample handed out (after
    /// [`Sub::latest`]: of the newest one). Tells two publishers of one `Source` apart.
    pub origin: u128,
    /// Valid samples dropped by [`Sub::latest_from`] because their publisher was not accepted.
    pub foreign: u64,
}

/// Reads a single-publisher service (the robot state) from the publisher first heard, the
/// one the run started: valid samples of any other (a rogue `sim` on the run) are dropped and
/// counted in [`Sub::foreign`]. If the followed publisher leaves the service, the next one
/// heard takes over (a restarted driver). The tracker and every other reader of the robot
/// state use it: a planner that planned from a rogue's states spliced trajectories where
/// the arm was not.
#[derive(Debug, Clone, Copy, Default)]
pub struct PublisherLock {
    id: Option<u128>,
    foreign_seen: u64,
}

impl PublisherLock {
    /// [`Sub::latest`] from the followed publisher; true if it had a new sample.
    pub fn latest<T: Topic>(
        &mut self,
        bus: &Bus,
        sub: &mut Sub<T>,
        out: &mut T,
        lim: &ContractLimits,
    ) -> Result<bool, BusError> {
        let lock = self.id;
        let got = sub.latest_from(out, lim, |o| lock.is_none_or(|l| l == o))?;
        if got {
            self.id.get_or_insert(sub.origin);
        }
        if sub.foreign > self.foreign_seen {
            self.foreign_seen = sub.foreign;
            // Gone only if the service says so (an error listing it is no reason to switch).
            if self.id.is_some_and(|l| bus.publisher_ids::<T>().is_ok_and(|ids| !ids.contains(&l))) {
                self.id = None;
            }
        }
        Ok(got)
    }
}

impl<T: Topic> Sub<T> {
    /// Why the newest refused sample was refused, naming the service and the contract's field
    /// (`None`: none was refused). Allocates: for reports, not for hot loops.
    pub fn rejection(&self) -> Option<String> {
        self.last_error.as_ref().map(|e| format!("{}: {e}", T::SERVICE))
    }

    /// Drains the queue; copies the newest *valid* sample into `out` (its used part:
    /// [`UsedPart`]) and returns true if there was one. Invalid samples are counted and
    /// dropped.
    pub fn latest(&mut self, out: &mut T, lim: &ContractLimits) -> Result<bool, BusError> {
        let mut got = false;
        self.for_each_checked(
            |m| m.validate(lim),
            |m| {
                // SAFETY: `out` is a valid, aligned T.
                unsafe { m.write_used(out) };
                got = true;
            },
        )?;
        Ok(got)
    }

    /// Like [`Sub::latest`], from the publishers `accept` takes (by iceoryx2 publisher id, as
    /// in [`Sub::origin`]) only: valid samples of any other publisher are counted in
    /// [`Sub::foreign`] and dropped (a rogue publisher on a single-publisher service).
    pub fn latest_from(
        &mut self,
        out: &mut T,
        lim: &ContractLimits,
        accept: impl Fn(u128) -> bool,
    ) -> Result<bool, BusError> {
        let mut got = None;
        let mut foreign = 0;
        self.drain(
            |m| m.validate(lim),
            |m, origin| {
                if accept(origin) {
                    // SAFETY: `out` is a valid, aligned T.
                    unsafe { m.write_used(out) };
                    got = Some(origin);
                } else {
                    foreign += 1;
                }
            },
        )?;
        self.foreign += foreign;
        if let Some(o) = got {
            self.origin = o;
        }
        Ok(got.is_some())
    }

    /// Like [`Sub::latest`] but calls `f` for every valid sample in order.
    pub fn for_each(&mut self, lim: &ContractLimits, f: impl FnMut(&T)) -> Result<usize, BusError> {
        self.for_each_checked(|m| m.validate(lim), f)
    }
}

impl<T: Topic> Sub<T> {
    /// Like [`Sub::for_each`] with a caller-chosen check instead of [`Validate::validate`]
    /// (e.g. a frame-level check, the items then checked one by one so that one bad item
    /// does not lose the good ones). Rejects are counted the same way.
    pub fn for_each_checked(
        &mut self,
        check: impl Fn(&T) -> Result<(), ValidationError>,
        mut f: impl FnMut(&T),
    ) -> Result<usize, BusError> {
        let mut origin = None;
        let n = self.drain(check, |m, o| {
            origin = Some(o);
            f(m)
        })?;
        if let Some(o) = origin {
            self.origin = o;
        }
        Ok(n)
    }

    /// Drains the queue: `f(sample, publisher id)` for every sample `check` passes; the
    /// others are counted as rejected.
    fn drain(
        &mut self,
        check: impl Fn(&T) -> Result<(), ValidationError>,
        mut f: impl FnMut(&T, u128),
    ) -> Result<usize, BusError> {
        let mut n = 0;
        while let Some(sample) =
            self.port.receive().map_err(|e| err(format!("receive on {}", T::SERVICE), e))?
        {
            self.received += 1;
            let h = sample.payload().header();
            if let Some((source, seq)) = self.last {
                if source == h.source && h.seq > seq + 1 {
                    self.lost += h.seq - seq - 1;
                }
            }
            self.last = Some((h.source, h.seq));
            match check(sample.payload()) {
                Ok(()) => {
                    f(sample.payload(), sample.header().publisher_id().value());
                    n += 1;
                }
                Err(e) => {
                    self.rejected += 1;
                    self.last_error = Some(e);
                }
            }
        }
        Ok(n)
    }
}

/// Rate-limited heartbeat publisher (every process sends one at `hz`).
pub struct HeartbeatTx {
    port: Pub<Heartbeat>,
    period_ns: u64,
    next_ns: u64,
    msg: Heartbeat,
}

impl HeartbeatTx {
    pub fn new(bus: &Bus, source: Source, hz: f64) -> Result<HeartbeatTx, BusError> {
        let port = bus.publisher::<Heartbeat>(source)?;
        let mut msg = <Heartbeat as Zeroed>::zeroed();
        msg.header = Header::new(source);
        Ok(HeartbeatTx { port, period_ns: (1e9 / hz.max(0.1)) as u64, next_ns: 0, msg })
    }

    /// Sends a heartbeat if one is due at `now_ns` (CLOCK_MONOTONIC), or if `force`.
    #[allow(clippy::too_many_arguments)]
    pub fn maybe_send(
        &mut self,
        now_ns: u64,
        force: bool,
        stamp_ns: u64,
        state: ProcessState,
        ticks: u64,
        deadline_misses: u64,
        rejected: u64,
        safe_hold_entries: u64,
    ) -> Result<bool, BusError> {
        if !force && now_ns < self.next_ns {
            return Ok(false);
        }
        self.next_ns = now_ns + self.period_ns;
        let m = &mut self.msg;
        m.header.stamp_ns = stamp_ns;
        m.state = state as u32;
        m.ticks = ticks;
        m.deadline_misses = deadline_misses;
        m.rejected = rejected;
        m.safe_hold_entries = safe_hold_entries;
        let mut msg = *m;
        self.port.publish(&mut msg)?;
        Ok(true)
    }
}
