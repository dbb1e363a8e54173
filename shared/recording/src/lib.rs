//! dkrrt-recording: a run's messages in an MCAP file.
//!
//! Every service is one MCAP channel (`/dkrrt/robot_state`, …) with `json` message encoding
//! and a `jsonschema` schema, so Foxglove Studio shows the fields. Only the used part of a
//! fixed-capacity message is written (the `count` items of a frame, the `steps` of a track,
//! the `n_seg` segments of a joint). Records are written unchunked through a buffer flushed
//! every [`FLUSH_NS`]: an interrupted recording (the recorder killed, the disk full) is
//! readable up to the last flush ([`read`] stops at the first broken record).
//!
//! The payloads the predictor and the planner consume from the arm side (`RobotState`,
//! `TorqueCommand`, `DebrisObservation`, `Goal`) decode back exactly (JSON numbers
//! round-trip f64), so `dkrrt replay` can republish them.

use std::collections::BTreeMap;
use std::io::BufWriter;
use std::path::Path;

use dkrrt_msg::bus::Topic;
use dkrrt_msg::*;
use serde_json::{json, Value};

/// The recorder flushes its buffer at least this often (plant-independent wall time), ns.
pub const FLUSH_NS: u64 = 100_000_000;

/// Largest recording `dkrrt replay` reads, bytes.
pub const MAX_RECORDING_BYTES: u64 = 4 << 30;

/// A payload that can be recorded (and, for some, decoded back).
pub trait Recordable: Topic {
    /// JSON of the used part of the message.
    fn to_json(&self) -> Value;
    /// The message from its JSON (`None`: not decodable, or this type is view-only).
    fn from_json(_v: &Value) -> Option<Self> {
        None
    }
}

fn hdr(h: &Header) -> Value {
    json!({"seq": h.seq, "stamp_ns": h.stamp_ns, "mono_ns": h.mono_ns, "source": h.source, "flags": h.flags})
}

fn f(v: &Value, k: &str) -> Option<f64> {
    v.get(k)?.as_f64()
}

fn u(v: &Value, k: &str) -> Option<u64> {
    v.get(k)?.as_u64()
}

fn arr<const N: usize>(v: &Value, k: &str) -> Option<[f64; N]> {
    let a = v.get(k)?.as_array()?;
    if a.len() != N {
        return None;
    }
    let mut out = [0.0; N];
    for (o, x) in out.iter_mut().zip(a) {
        *o = x.as_f64()?;
    }
    Some(out)
}

fn header_from(v: &Value) -> Option<Header> {
    let h = v.get("header")?;
    Some(Header {
        seq: u(h, "seq")?,
        stamp_ns: u(h, "stamp_ns")?,
        mono_ns: u(h, "mono_ns")?,
        source: u(h, "source")? as u32,
        flags: u(h, "flags")? as u32,
    })
}

fn shape(s: &DebrisShape) -> Value {
    json!({"kind": s.kind, "dims": s.dims, "offset": s.offset})
}

fn shape_from(v: &Value) -> Option<DebrisShape> {
    Some(DebrisShape {
        kind: u(v, "kind")? as u32,
        _reserved: 0,
        dims: arr(v, "dims")?,
        offset: arr(v, "offset")?,
    })
}

impl Recordable for RobotState {
    fn to_json(&self) -> Value {
        json!({"header": hdr(&self.header), "q": self.q, "qd": self.qd, "tau": self.tau})
    }
    fn from_json(v: &Value) -> Option<Self> {
        Some(RobotState { header: header_from(v)?, q: arr(v, "q")?, qd: arr(v, "qd")?, tau: arr(v, "tau")? })
    }
}

impl Recordable for TorqueCommand {
    fn to_json(&self) -> Value {
        json!({"header": hdr(&self.header), "tau": self.tau, "q_set": self.q_set, "qd_set": self.qd_set, "state_seq": self.state_seq, "mode": self.mode, "traj_id": self.traj_id})
    }
    fn from_json(v: &Value) -> Option<Self> {
        Some(TorqueCommand {
            header: header_from(v)?,
            tau: arr(v, "tau")?,
            q_set: arr(v, "q_set")?,
            qd_set: arr(v, "qd_set")?,
            state_seq: u(v, "state_seq")?,
            mode: u(v, "mode")? as u32,
            traj_id: u(v, "traj_id")? as u32,
        })
    }
}

impl Recordable for Goal {
    fn to_json(&self) -> Value {
        json!({"header": hdr(&self.header), "goal_id": self.goal_id, "kind": self.kind, "q": self.q, "pose_p": self.pose_p, "pose_q": self.pose_q})
    }
    fn from_json(v: &Value) -> Option<Self> {
        Some(Goal {
            header: header_from(v)?,
            goal_id: u(v, "goal_id")?,
            kind: u(v, "kind")? as u32,
            _pad: 0,
            q: arr(v, "q")?,
            pose_p: arr(v, "pose_p")?,
            pose_q: arr(v, "pose_q")?,
        })
    }
}

impl Recordable for DebrisObservation {
    fn to_json(&self) -> Value {
        let n = (self.count as usize).min(MAX_DEBRIS);
        let items: Vec<Value> = self.items[..n]
            .iter()
            .map(|o| {
                json!({"id": o.id, "flags": o.flags, "t_meas_ns": o.t_meas_ns, "p": o.p, "q": o.q, "v": o.v, "w": o.w,
                       "bounding_radius": o.bounding_radius, "shape": shape(&o.shape)})
            })
            .collect();
        json!({"header": hdr(&self.header), "count": self.count, "items": items})
    }
    fn from_json(v: &Value) -> Option<Self> {
        let mut m = <DebrisObservation as Zeroed>::zeroed();
        m.header = header_from(v)?;
        let items = v.get("items")?.as_array()?;
        if items.len() > MAX_DEBRIS || u(v, "count")? as usize != items.len() {
            return None;
        }
        m.count = items.len() as u32;
        for (o, x) in m.items.iter_mut().zip(items) {
            *o = DebrisObs {
                id: u(x, "id")? as u32,
                flags: u(x, "flags")? as u32,
                t_meas_ns: u(x, "t_meas_ns")?,
                p: arr(x, "p")?,
                q: arr(x, "q")?,
                v: arr(x, "v")?,
                w: arr(x, "w")?,
                bounding_radius: f(x, "bounding_radius")?,
                shape: shape_from(x.get("shape")?)?,
            };
        }
        Some(m)
    }
}

impl Recordable for Trajectory {
    fn to_json(&self) -> Value {
        let joints: Vec<Value> = (0..NJ)
            .map(|j| {
                let n = (self.n_seg[j] as usize).min(MAX_SEGMENTS);
                Value::Array(
                    self.seg[j][..n]
                        .iter()
                        .map(|s| json!({"t0": s.t0, "p": s.p, "v": s.v, "a": s.a, "j": s.j}))
                        .collect(),
                )
            })
            .collect();
        json!({"header": hdr(&self.header), "traj_id": self.traj_id, "start_ns": self.start_ns, "duration_s": self.duration_s, "n_seg": self.n_seg, "segments": joints})
    }
}

impl Recordable for DebrisForecast {
    fn to_json(&self) -> Value {
        let (n, s) = ((self.count as usize).min(MAX_DEBRIS), (self.steps as usize).min(FORECAST_STEPS));
        let tracks: Vec<Value> = self.tracks[..n]
            .iter()
            .map(|t| {
                let steps: Vec<Value> = t.steps[..s]
                    .iter()
                    .map(|st| json!({"p": st.p, "q": st.q, "sigma_m": st.sigma_m, "sigma_pos_m": st.sigma_pos_m}))
                    .collect();
                json!({"id": t.id, "bounding_radius": t.bounding_radius, "shape": shape(&t.shape), "steps": steps})
            })
            .collect();
        json!({"header": hdr(&self.header), "count": self.count, "steps": self.steps, "dt_s": self.dt_s, "t0_ns": self.t0_ns, "tracks": tracks})
    }
}

impl Recordable for PlanStatus {
    fn to_json(&self) -> Value {
        json!({"header": hdr(&self.header), "cycle": self.cycle, "plan_time_us": self.plan_time_us, "iterations": self.iterations,
               "fallback": self.fallback, "replans": self.replans, "active_traj_id": self.active_traj_id,
               "min_predicted_clearance_m": finite_or_null(self.min_predicted_clearance_m), "goal_reached": self.goal_reached,
               "deadline_missed": self.deadline_missed})
    }
}

impl Recordable for Heartbeat {
    fn to_json(&self) -> Value {
        json!({"header": hdr(&self.header), "state": self.state, "ticks": self.ticks, "deadline_misses": self.deadline_misses,
               "rejected": self.rejected, "safe_hold_entries": self.safe_hold_entries})
    }
}

impl Recordable for PredictorProgress {
    fn to_json(&self) -> Value {
        json!({"header": hdr(&self.header), "frame_seq": self.frame_seq, "frames": self.frames, "forecasts": self.forecasts})
    }
}

/// JSON has no Inf (a clearance with nothing in range is +Inf).
fn finite_or_null(x: f64) -> Value {
    if x.is_finite() {
        json!(x)
    } else {
        Value::Null
    }
}

/// A JSON schema of a recorded message, derived from a sample's JSON (the field names and
/// kinds Foxglove lists).
pub fn schema_of(sample: &Value) -> Value {
    match sample {
        Value::Object(m) => {
            let props: serde_json::Map<String, Value> =
                m.iter().map(|(k, v)| (k.clone(), schema_of(v))).collect();
            json!({"type": "object", "properties": props})
        }
        Value::Array(a) => match a.first() {
            Some(x) => json!({"type": "array", "items": schema_of(x)}),
            None => json!({"type": "array"}),
        },
        Value::Number(n) if n.is_f64() => json!({"type": "number"}),
        Value::Number(_) => json!({"type": "integer"}),
        Value::Bool(_) => json!({"type": "boolean"}),
        Value::String(_) => json!({"type": "string"}),
        Value::Null => json!({"type": ["number", "null"]}),
    }
}

/// The MCAP topic of a service.
pub fn topic_of(service: &str) -> String {
    format!("/{service}")
}

/// Writes a recording. Memory is bounded by the write buffer; nothing grows per message.
pub struct Recorder {
    w: mcap::Writer<BufWriter<std::fs::File>>,
    channels: BTreeMap<&'static str, u16>,
    seq: u32,
    buf: Vec<u8>,
    pub messages: u64,
}

impl Recorder {
    /// Creates `path` (never overwriting: an existing file is an error).
    pub fn create(path: &Path) -> Result<Recorder, String> {
        let file = std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(path)
            .map_err(|e| format!("{}: {e}", path.display()))?;
        let w = mcap::WriteOptions::new()
            .use_chunks(false)
            .profile("")
            .library("dkrrt")
            .create(BufWriter::with_capacity(1 << 20, file))
            .map_err(|e| format!("{}: {e}", path.display()))?;
        Ok(Recorder { w, channels: BTreeMap::new(), seq: 0, buf: Vec::with_capacity(1 << 16), messages: 0 })
    }

    /// Records `msg` at `log_time_ns` (the recorder's CLOCK_MONOTONIC); the channel (and its
    /// schema) is added at the first message of its service.
    pub fn record<T: Recordable>(&mut self, msg: &T, log_time_ns: u64) -> Result<(), String> {
        let v = msg.to_json();
        let id = match self.channels.get(T::SERVICE) {
            Some(id) => *id,
            None => {
                let schema = serde_json::to_vec(&schema_of(&v)).map_err(|e| e.to_string())?;
                let name = T::SERVICE.trim_start_matches("dkrrt/");
                let sid = self.w.add_schema(name, "jsonschema", &schema).map_err(|e| e.to_string())?;
                let cid = self
                    .w
                    .add_channel(sid, &topic_of(T::SERVICE), "json", &BTreeMap::new())
                    .map_err(|e| e.to_string())?;
                self.channels.insert(T::SERVICE, cid);
                cid
            }
        };
        self.buf.clear();
        serde_json::to_writer(&mut self.buf, &v).map_err(|e| e.to_string())?;
        self.seq = self.seq.wrapping_add(1);
        let h = mcap::records::MessageHeader {
            channel_id: id,
            sequence: self.seq,
            log_time: log_time_ns,
            publish_time: msg.header().mono_ns,
        };
        self.w.write_to_known_channel(&h, &self.buf).map_err(|e| e.to_string())?;
        self.messages += 1;
        Ok(())
    }

    /// Pushes everything written so far to the file (readable up to here if interrupted).
    pub fn flush(&mut self) -> Result<(), String> {
        self.w.flush().map_err(|e| e.to_string())?;
        Ok(())
    }

    /// Writes the summary and closes the file.
    pub fn finish(mut self) -> Result<u64, String> {
        self.w.finish().map_err(|e| e.to_string())?;
        Ok(self.messages)
    }
}

/// One recorded message.
#[derive(Debug, Clone)]
pub struct Recorded {
    pub topic: String,
    pub log_time_ns: u64,
    pub json: Value,
}

/// Reads a recording in file order, up to its end or the first broken record (an
/// interrupted recording). Returns the messages and whether the file was complete.
pub fn read(path: &Path) -> Result<(Vec<Recorded>, bool), String> {
    let bytes =
        dkrrt_io::read_capped(path, MAX_RECORDING_BYTES).map_err(|e| format!("{}: {e}", path.display()))?;
    // An interrupted recording lacks its end, never its start: a file that does not begin
    // with the MCAP magic is not a recording (not an empty, interrupted one).
    if !bytes.starts_with(mcap::MAGIC) {
        return Err(format!(
            "{}: not an MCAP recording (its first bytes are not the MCAP magic)",
            path.display()
        ));
    }
    let opts = mcap::read::Options::IgnoreEndMagic.into();
    let stream = mcap::MessageStream::new_with_options(&bytes, opts)
        .map_err(|e| format!("{}: {e}", path.display()))?;
    let mut out = Vec::new();
    let mut complete = true;
    for m in stream {
        match m {
            Ok(m) => {
                let json = serde_json::from_slice(&m.data)
                    .map_err(|e| format!("{}: message {}: {e}", path.display(), out.len()))?;
                out.push(Recorded { topic: m.channel.topic.clone(), log_time_ns: m.log_time, json });
            }
            Err(_) => {
                complete = false;
                break;
            }
        }
    }
    Ok((out, complete))
}
