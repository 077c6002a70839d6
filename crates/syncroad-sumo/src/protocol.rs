//! The pipe protocol between the parent and a worker.
//!
//! The parent writes one JSON line, a [`Request`], to the worker's stdin. The worker answers on
//! its protocol channel (its original stdout; SUMO's own console output is diverted to stderr)
//! with frames `[kind: u8][len: u32 LE][payload]`:
//! * kind `J`: a JSON [`WorkerMsg`] (start info, events, the end of the run);
//! * kind `R`: a binary chunk of trajectory rows, see [`RowChunk`]: `n: u32, records: u32`, then
//!   per record `t, speeds, positions, commands` as little-endian f64.
//!
//! Rows stream in chunks while the control loop runs inside the worker, so the parent holds
//! every row received so far whatever happens to the worker.

use std::io::{self, Read, Write};
use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use syncroad_control::record::Measured;
use syncroad_control::sumo_facts::Emissions;
use syncroad_control::{LawSpec, StopReason, Trajectory};

use crate::layout::Layout;
use crate::probe::{Probe, ProbeTimes};
use crate::python::PythonInfo;

/// Frame kind of a JSON message.
pub const KIND_JSON: u8 = b'J';
/// Frame kind of a row chunk.
pub const KIND_ROWS: u8 = b'R';
/// Frame kind of the speed ranges of every step: `(t, min v_i, max v_i)` over the vehicles the
/// run judges (the leader vehicle excluded), whatever the recording stride.
pub const KIND_RANGES: u8 = b'S';
/// Largest frame accepted \[bytes\]; a longer length means a corrupted stream.
pub const MAX_FRAME: usize = 1 << 30;

/// One line to a worker: a run, or a run the benchmark times (what the worker reads).
#[derive(Debug, Clone, Deserialize)]
#[serde(tag = "job", rename_all = "snake_case")]
pub enum Job {
    /// A run.
    Run(Box<Request>),
    /// A run under the benchmark's probe (see [`crate::probe`]).
    Bench {
        /// The run, as a run would send it.
        request: Box<Request>,
        /// What to time.
        probe: Probe,
    },
}

impl Job {
    /// The run of this job.
    pub fn request(&self) -> &Request {
        match self {
            Job::Run(r) | Job::Bench { request: r, .. } => r,
        }
    }
}

/// A [`Job`] as the parent sends it, borrowing its request.
#[derive(Debug, Clone, Copy, Serialize)]
#[serde(tag = "job", rename_all = "snake_case")]
pub(crate) enum JobRef<'a> {
    /// A run.
    Run(&'a Request),
    /// A run under the benchmark's probe.
    Bench {
        /// The run.
        request: &'a Request,
        /// What to time.
        probe: Probe,
    },
}

impl<'a> JobRef<'a> {
    /// The run of this job.
    pub fn request(&self) -> &'a Request {
        match *self {
            JobRef::Run(r) | JobRef::Bench { request: r, .. } => r,
        }
    }

    /// The job itself, owned (for a run on a thread of this process).
    pub fn to_job(self) -> Job {
        match self {
            JobRef::Run(r) => Job::Run(Box::new(r.clone())),
            JobRef::Bench { request, probe } => Job::Bench {
                request: Box::new(request.clone()),
                probe,
            },
        }
    }
}

/// What the worker is asked to do.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Request {
    /// The vehicles, the road and the routes.
    pub layout: Layout,
    /// The routes file written by the parent from `layout`.
    pub routes_file: PathBuf,
    /// SUMO's message log (`--log`).
    pub log_file: PathBuf,
    /// Step Δt \[s\].
    pub step_s: f64,
    /// Number of steps after insertion.
    pub steps: usize,
    /// SUMO's random seed (`--seed`).
    pub seed: u64,
    /// `--step-method.ballistic`: positions by the trapezoidal rule (true) or SUMO's default
    /// semi-implicit Euler `x += v^{n+1} Δt` (false).
    pub ballistic: bool,
    /// Who drives.
    pub control: Control,
    /// Record every k-th step.
    pub record_every: usize,
    /// Records per row chunk.
    pub chunk_records: usize,
    /// A realised speed further than this from the command counts as overridden [m/s].
    pub override_tolerance_mps: f64,
    /// How states are read.
    #[serde(default)]
    pub read: ReadMode,
    /// With [`ReadMode::Getters`], read SUMO's odometer every this many steps.
    pub odometer_every: usize,
    /// Speed mode of the vehicles the law commands, from the safety layer
    /// ([`syncroad_control::safety::SafetyMode::speed_mode`]).
    #[serde(default = "default_speed_mode")]
    pub speed_mode: i32,
    /// The safety layer under the law (`off`, SUMO's checks, or syncroad's filter).
    #[serde(default = "default_safety")]
    pub safety: syncroad_control::safety::SafetyMode,
    /// What SUMO itself measures during the run (flow, time loss, fuel, CO2, braking).
    #[serde(default)]
    pub measure: Option<Measure>,
    /// The user's own route files, loaded after syncroad's (`sumo.routes`).
    #[serde(default)]
    pub extra_routes: Vec<PathBuf>,
    /// The user's own additional files (`sumo.additional`).
    #[serde(default)]
    pub extra_additional: Vec<PathBuf>,
    /// Take the law's graph from SUMO each step and count how often the vehicle ahead of one
    /// of syncroad's vehicles changes (other traffic shares the road).
    #[serde(default)]
    pub sense_graph: bool,
    /// SUMO's summary output (every vehicle in the network), written when other traffic
    /// shares the road.
    #[serde(default)]
    pub summary_file: Option<PathBuf>,
    /// The run's warm-up \[s\]: what SUMO's files read after the run (its summary, its
    /// surrogate safety measures) measure from it.
    #[serde(default)]
    pub warmup_s: f64,
    /// SUMO's floating-car data of every vehicle (`--fcd`), for replay.
    #[serde(default)]
    pub fcd_file: Option<PathBuf>,
    /// The floating-car data is written every this many steps (0 and 1: every step).
    #[serde(default)]
    pub fcd_every: usize,
    /// The law drives these of the user's own vehicles (`sumo.controlled`), bound after
    /// insertion in their order along the road; syncroad inserts no vehicle, and
    /// `layout.vehicles` holds placeholders until the worker has bound them.
    #[serde(default)]
    pub adopt: Option<syncroad_control::scenario::VehicleSelector>,
    /// The laws that drive the vehicles of the inflows they control
    /// (`sumo.inflows[k].controlled`), each vehicle from its entry to its exit.
    #[serde(default)]
    pub guests: Vec<GuestLaw>,
}

/// The law that drives an inflow's controlled vehicles: the worker recognises them by their
/// vehicle type when SUMO inserts them and builds the law for each one alone.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GuestLaw {
    /// The inflow (`sumo.inflows[k]`); its vehicles the law drives are of the type
    /// [`crate::inflows::guest_type`]`(k)`.
    pub inflow: usize,
    /// The law: a registry law by its name and parameters, or the user's Python class (one
    /// instance per vehicle).
    pub law: syncroad_control::UserLaw,
    /// What it is built with for one vehicle (an open road: nobody ahead but whom SUMO
    /// reports).
    pub context: syncroad_control::speed_controller::LawContext,
    /// Their type's `minGap` \[m\]: SUMO reports the distance to the vehicle ahead from the
    /// front bumper plus it.
    pub min_gap_m: f64,
}

fn default_speed_mode() -> i32 {
    32
}

fn default_safety() -> syncroad_control::safety::SafetyMode {
    syncroad_control::safety::SafetyMode::Off
}

/// SUMO-side measurements the loop collects after a warm-up (see [`Measured`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Measure {
    /// Steps after insertion before measuring starts.
    pub warmup_steps: usize,
    /// Read fuel and CO2 rates every this many steps and hold each reading for that many
    /// steps (1 = exact rectangle rule at SUMO's step).
    pub emission_every: usize,
    /// Additional file holding the E1 induction loop `loop0`, when the road has one.
    pub detector_file: Option<PathBuf>,
    /// SUMO's trip-info output with emission totals of unfinished trips (cross-checks).
    pub tripinfo_file: Option<PathBuf>,
    /// Log of SUMO's SSM device (TTC and DRAC conflicts of every vehicle), when asked for.
    #[serde(default)]
    pub ssm_file: Option<PathBuf>,
    /// The emission sums to read (each read runs SUMO's emission model for every vehicle).
    #[serde(default)]
    pub emissions: Emissions,
}

/// How the loop reads vehicle states from libsumo.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ReadMode {
    /// As [`ReadMode::Getters`], but the per-vehicle `getSpeed`/`setSpeed`/`getDistance` go
    /// straight to the C++ functions of the libsumo Python loaded, one batch per step
    /// ([`crate::direct`]); falls back to the getters if that library does not export them.
    #[default]
    Direct,
    /// `vehicle.getSpeed` per vehicle per step through Python, odometer every few steps.
    Getters,
    /// Subscriptions to speed and odometer, one `getAllSubscriptionResults` per step.
    Subscriptions,
}

/// Who drives the vehicles.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum Control {
    /// The scenario's law, resolved by the parent (nothing is validated twice).
    Law {
        /// The model, step and initial speeds.
        law: Box<LawSpec>,
    },
    /// SUMO's own car-following model (Krauss with the layout's σ); nothing is commanded.
    SumoModel,
}

/// A JSON message from the worker.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "msg", rename_all = "snake_case")]
pub enum WorkerMsg {
    /// SUMO is running and every vehicle is on the road.
    Started(StartInfo),
    /// Something happened at a step.
    Event(Event),
    /// The run ended (normally or with a typed stop reason).
    Finished(Box<Finish>),
    /// The worker failed cleanly (Python exception, vehicles left pending, ...).
    Failed {
        /// The error, with its Python traceback when there is one.
        message: String,
    },
    /// The worker refused the run before SUMO started: its law could not be built (the
    /// user's controller: a missing file or class, parameters its `__init__` refused).
    Refused {
        /// Why, with the Python traceback when there is one.
        message: String,
    },
}

/// What the worker found when SUMO started.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct StartInfo {
    /// The embedded interpreter and libsumo.
    pub python: PythonInfo,
    /// Road length from libsumo `lane.getLength`, normal plus internal lanes \[m\].
    pub road_length_m: f64,
    /// Number of vehicles on the road after insertion.
    pub vehicles: usize,
    /// Process id of the worker.
    pub pid: u32,
    /// The user's vehicles the law drives (`sumo.controlled`), in the layout's order (empty:
    /// syncroad's own).
    #[serde(default)]
    pub controlled: Vec<String>,
}

/// A step event.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Event {
    /// SUMO reported colliding vehicles (`simulation.getCollidingVehiclesNumber`).
    Collision {
        /// Step index (after the step).
        step: usize,
        /// Vehicles involved.
        vehicles: usize,
    },
    /// Vehicles started teleporting.
    Teleport {
        /// Step index.
        step: usize,
        /// Number of teleports started.
        count: usize,
    },
    /// SUMO did not realise a command (only the first few per run are sent; all are counted).
    Override {
        /// Step index at which the speed was measured.
        step: usize,
        /// SUMO vehicle id.
        vehicle: String,
        /// Commanded speed [m/s].
        commanded_mps: f64,
        /// Realised speed [m/s].
        realised_mps: f64,
    },
}

/// Counters of a run.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Totals {
    /// Steps with at least one collision.
    pub collision_steps: usize,
    /// Sum over steps of colliding vehicles.
    pub colliding_vehicles: usize,
    /// Teleports started.
    pub teleports: usize,
    /// Commands SUMO did not realise within the tolerance.
    pub overrides: usize,
    /// Largest |realised − commanded| [m/s].
    pub max_override_mps: f64,
    /// Negative commands sent as 0 (SUMO reads a negative speed as "release control").
    pub negative_commands_clamped: usize,
    /// Largest difference between SUMO's odometer and the positions integrated from the
    /// measured speeds with SUMO's update rule \[m\] (0 up to rounding).
    pub odometer_deviation_max_m: f64,
    /// The per-vehicle calls went straight to libsumo's C++ functions ([`ReadMode::Direct`]).
    #[serde(default)]
    pub direct_calls: bool,
    /// Changes of the vehicle ahead of a controlled vehicle, when watched.
    #[serde(default)]
    pub topology_changes: Option<usize>,
    /// Vehicles `sumo.controlled` chooses that came onto the road after the start and were
    /// driven by their own vehicle type, when the law drove the user's own.
    #[serde(default)]
    pub chosen_later: Option<usize>,
    /// What syncroad's safety filter under the law did, when it ran.
    #[serde(default)]
    pub filter: Option<syncroad_control::speed_controller::FilterReport>,
    /// The inflows' controlled vehicles, when some inflow has them.
    #[serde(default)]
    pub guests: Option<Box<syncroad_control::sumo_facts::Guests>>,
}

/// The end of a run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Finish {
    /// Why it stopped.
    pub stop: StopReason,
    /// Steps completed.
    pub steps_done: usize,
    /// Counters.
    pub totals: Totals,
    /// What the benchmark's probe measured (a [`Job::Bench`] only).
    #[serde(default)]
    pub probe: Option<ProbeTimes>,
    /// SUMO-side measurements, when requested.
    #[serde(default)]
    pub measured: Option<Measured>,
    /// Wall time spent inside SUMO's `simulation.step` over the run's full steps \[s\]: what
    /// a sweep's stepping bound is made of. A timing, so never part of a run's record.
    #[serde(default)]
    pub step_s: f64,
}

/// One frame built in place, header first (`[kind][len]`, the length patched when it is
/// written), so that a frame goes out in one write with no copy of its payload; the buffer is
/// reused frame after frame.
#[derive(Debug)]
struct FrameBuf {
    bytes: Vec<u8>,
}

/// Bytes of a frame's header: kind and length.
const FRAME_HEAD: usize = 5;

impl FrameBuf {
    fn new(kind: u8, payload: usize) -> Self {
        let mut bytes = Vec::with_capacity(FRAME_HEAD + payload);
        bytes.push(kind);
        bytes.extend_from_slice(&0u32.to_le_bytes());
        Self { bytes }
    }

    /// The payload so far.
    fn payload_mut(&mut self) -> &mut [u8] {
        &mut self.bytes[FRAME_HEAD..]
    }

    /// Appends `xs` as little-endian f64: one copy of the slice's bytes on a little-endian
    /// machine.
    fn extend_f64(&mut self, xs: &[f64]) {
        #[cfg(target_endian = "little")]
        self.bytes.extend_from_slice(bytemuck::cast_slice(xs));
        #[cfg(not(target_endian = "little"))]
        for x in xs {
            self.bytes.extend_from_slice(&x.to_le_bytes());
        }
    }

    /// Writes the frame in one `write_all`, then keeps the first `keep` payload bytes for the
    /// next frame.
    fn write(&mut self, w: &mut impl Write, keep: usize) -> io::Result<()> {
        let len = (self.bytes.len() - FRAME_HEAD) as u32;
        self.bytes[1..FRAME_HEAD].copy_from_slice(&len.to_le_bytes());
        w.write_all(&self.bytes)?;
        self.bytes.truncate(FRAME_HEAD + keep);
        Ok(())
    }
}

/// The speed ranges of the steps since the last frame (`t, lo, hi` triplets), encoded as they
/// come into one reused frame.
#[derive(Debug)]
pub struct RangeChunk {
    frame: FrameBuf,
}

impl Default for RangeChunk {
    fn default() -> Self {
        Self {
            frame: FrameBuf::new(KIND_RANGES, 24 * 1024),
        }
    }
}

impl RangeChunk {
    /// Appends the range of one step.
    pub fn push(&mut self, t: f64, lo: f64, hi: f64) {
        self.frame.extend_f64(&[t, lo, hi]);
    }

    /// True when nothing is held.
    pub fn is_empty(&self) -> bool {
        self.frame.bytes.len() == FRAME_HEAD
    }

    /// Writes the held ranges as one frame (nothing when empty) and empties the chunk.
    pub fn write(&mut self, w: &mut impl Write) -> io::Result<()> {
        if self.is_empty() {
            return Ok(());
        }
        self.frame.write(w, 0)
    }
}

fn decode_ranges(bytes: &[u8]) -> Result<Vec<[f64; 3]>, ProtocolError> {
    if !bytes.len().is_multiple_of(24) {
        return Err(ProtocolError::Json(format!(
            "speed-range frame of {} bytes is not a whole number of 24-byte records",
            bytes.len()
        )));
    }
    Ok(bytes
        .chunks_exact(24)
        .map(|c| {
            let f = |i: usize| f64::from_le_bytes(c[i..i + 8].try_into().expect("8 bytes"));
            [f(0), f(8), f(16)]
        })
        .collect())
}

/// Reads the payload of a [`RowChunk`] frame.
pub fn decode_rows(bytes: &[u8]) -> Result<Trajectory, ProtocolError> {
    let word = |i: usize| -> usize {
        bytes
            .get(i..i + 4)
            .map(|b| u32::from_le_bytes(b.try_into().expect("4 bytes")) as usize)
            .unwrap_or(0)
    };
    let (n, records) = (word(0), word(4));
    let expected = 8 + records * (1 + 4 * n) * 8;
    if bytes.len() != expected {
        return Err(ProtocolError::RowChunkSize {
            bytes: bytes.len(),
            expected,
            records,
            n,
        });
    }
    let mut floats = bytes[8..]
        .chunks_exact(8)
        .map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes")));
    let mut c = Trajectory::new(n);
    for _ in 0..records {
        c.time_s.push(floats.next().expect("sized"));
        for arr in [
            &mut c.speeds_mps,
            &mut c.positions_m,
            &mut c.commands_mps,
            &mut c.gaps_m,
        ] {
            arr.extend((&mut floats).take(n));
        }
    }
    Ok(c)
}

/// Errors decoding the worker's stream.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ProtocolError {
    /// Reading the pipe failed.
    #[error("reading from the worker failed: {0}")]
    Io(String),
    /// The stream ended inside a frame.
    #[error("frame of {len} bytes cut short: {reason}")]
    Truncated {
        /// Announced payload length (0 while reading the header).
        len: usize,
        /// The I/O error.
        reason: String,
    },
    /// A length beyond [`MAX_FRAME`].
    #[error("frame of {0} bytes exceeds the limit of {MAX_FRAME} bytes")]
    TooLong(usize),
    /// An unknown frame kind.
    #[error("unknown frame kind {0:#04x}")]
    UnknownKind(u8),
    /// A JSON frame that does not parse.
    #[error("bad JSON message: {0}")]
    Json(String),
    /// A row chunk whose size does not match its header.
    #[error(
        "row chunk of {bytes} bytes, expected {expected} for {records} records of {n} vehicles"
    )]
    RowChunkSize {
        /// Payload size.
        bytes: usize,
        /// Size implied by the header.
        expected: usize,
        /// Records announced.
        records: usize,
        /// Vehicles announced.
        n: usize,
    },
}

/// Writes one frame.
pub fn write_frame(w: &mut impl Write, kind: u8, payload: &[u8]) -> io::Result<()> {
    w.write_all(&[kind])?;
    w.write_all(&(payload.len() as u32).to_le_bytes())?;
    w.write_all(payload)
}

/// Writes a JSON message frame.
pub fn write_msg(w: &mut impl Write, msg: &WorkerMsg) -> io::Result<()> {
    let text = serde_json::to_vec(msg).map_err(io::Error::other)?;
    write_frame(w, KIND_JSON, &text)?;
    w.flush()
}

/// The worker's chunk of rows, encoded as it is recorded (the format is in the module's
/// documentation) into the frame's own buffer, which every chunk of the run reuses: no copy of
/// the rows into a trajectory first, no allocation per chunk, and the frame goes out in one
/// write.
#[derive(Debug)]
pub struct RowChunk {
    n: usize,
    records: usize,
    frame: FrameBuf,
}

impl RowChunk {
    /// An empty chunk for `n` vehicles, with room for `records` records.
    pub fn new(n: usize, records: usize) -> Self {
        let mut frame = FrameBuf::new(KIND_ROWS, 8 + records * (1 + 4 * n) * 8);
        frame.bytes.extend_from_slice(&(n as u32).to_le_bytes());
        frame.bytes.extend_from_slice(&0u32.to_le_bytes());
        Self {
            n,
            records: 0,
            frame,
        }
    }

    /// Records held.
    pub fn len(&self) -> usize {
        self.records
    }

    /// True when nothing is held.
    pub fn is_empty(&self) -> bool {
        self.records == 0
    }

    /// Appends the record at time `t`: each slice has one value per vehicle; `gaps` is each
    /// vehicle's gap to whoever is ahead as SUMO's road shows it (NaN: measured between
    /// syncroad's vehicles in their layout order, as without other traffic).
    pub fn push(
        &mut self,
        t: f64,
        speeds: &[f64],
        positions: &[f64],
        commands: &[f64],
        gaps: &[f64],
    ) {
        debug_assert!([speeds.len(), positions.len(), commands.len(), gaps.len()] == [self.n; 4]);
        self.frame.extend_f64(&[t]);
        for arr in [speeds, positions, commands, gaps] {
            self.frame.extend_f64(arr);
        }
        self.records += 1;
    }

    /// Writes the held records as one frame (nothing when empty) and empties the chunk.
    pub fn write(&mut self, w: &mut impl Write) -> io::Result<()> {
        if self.is_empty() {
            return Ok(());
        }
        let records = (self.records as u32).to_le_bytes();
        self.frame.payload_mut()[4..8].copy_from_slice(&records);
        self.frame.write(w, 8)?;
        self.records = 0;
        w.flush()
    }
}

/// A decoded frame.
#[derive(Debug)]
pub enum Frame {
    /// A JSON message.
    Msg(WorkerMsg),
    /// Rows.
    Rows(Trajectory),
    /// Speed ranges of every step.
    Ranges(Vec<[f64; 3]>),
}

/// Reads one frame; `Ok(None)` at a clean end of stream.
pub fn read_frame(r: &mut impl Read) -> Result<Option<Frame>, ProtocolError> {
    let mut head = [0u8; FRAME_HEAD];
    match r.read_exact(&mut head[..1]) {
        Ok(()) => {}
        Err(e) if e.kind() == io::ErrorKind::UnexpectedEof => return Ok(None),
        Err(e) => return Err(ProtocolError::Io(e.to_string())),
    }
    r.read_exact(&mut head[1..])
        .map_err(|e| ProtocolError::Truncated {
            len: 0,
            reason: e.to_string(),
        })?;
    let len = u32::from_le_bytes(head[1..FRAME_HEAD].try_into().expect("4 bytes")) as usize;
    if len > MAX_FRAME {
        return Err(ProtocolError::TooLong(len));
    }
    let mut payload = vec![0u8; len];
    r.read_exact(&mut payload)
        .map_err(|e| ProtocolError::Truncated {
            len,
            reason: e.to_string(),
        })?;
    match head[0] {
        KIND_JSON => serde_json::from_slice(&payload)
            .map(|m| Some(Frame::Msg(m)))
            .map_err(|e| ProtocolError::Json(e.to_string())),
        KIND_ROWS => decode_rows(&payload).map(|c| Some(Frame::Rows(c))),
        KIND_RANGES => decode_ranges(&payload).map(|r| Some(Frame::Ranges(r))),
        k => Err(ProtocolError::UnknownKind(k)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The row format written out from a whole trajectory, the reference [`RowChunk`] is
    /// checked against: `n: u32, records: u32`, then per record `t, speeds, positions,
    /// commands` as little-endian f64.
    fn encode_rows(rows: &Trajectory) -> Vec<u8> {
        let n = rows.n;
        let mut out = Vec::with_capacity(8 + rows.len() * (1 + 4 * n) * 8);
        out.extend_from_slice(&(n as u32).to_le_bytes());
        out.extend_from_slice(&(rows.len() as u32).to_le_bytes());
        for k in 0..rows.len() {
            out.extend_from_slice(&rows.time_s[k].to_le_bytes());
            for arr in [
                &rows.speeds_mps,
                &rows.positions_m,
                &rows.commands_mps,
                &rows.gaps_m,
            ] {
                for x in &arr[k * n..(k + 1) * n] {
                    out.extend_from_slice(&x.to_le_bytes());
                }
            }
        }
        out
    }

    #[test]
    fn rows_round_trip_through_frames() {
        let mut c = Trajectory::new(2);
        c.push_commanded(0.0, &[1.0, 2.0], &[0.0, -7.5], &[f64::NAN, 2.0]);
        c.push_commanded(0.1, &[1.5, 2.5], &[0.1, -7.3], &[1.5, 2.5]);
        // The gaps to whoever is ahead as SUMO saw it (NaN: between syncroad's own vehicles).
        c.gaps_m = vec![12.0, f64::NAN, 11.5, 3.25];
        let mut chunk = RowChunk::new(2, 1);
        for k in 0..c.len() {
            let at = k * 2..k * 2 + 2;
            chunk.push(
                c.time_s[k],
                &c.speeds_mps[at.clone()],
                &c.positions_m[at.clone()],
                &c.commands_mps[at.clone()],
                &c.gaps_m[at],
            );
        }
        let mut buf = Vec::new();
        chunk.write(&mut buf).unwrap();
        assert!(chunk.is_empty());
        // The frame built in place is the format's frame of the same records, header and all.
        let mut reference = Vec::new();
        write_frame(&mut reference, KIND_ROWS, &encode_rows(&c)).unwrap();
        assert_eq!(buf, reference);
        // An empty chunk writes nothing; the reused buffer encodes the next chunk afresh.
        chunk.write(&mut buf).unwrap();
        assert_eq!(buf.len(), 5 + encode_rows(&c).len());
        chunk.push(
            0.2,
            &[3.0, 4.0],
            &[0.4, -7.1],
            &[3.0, 4.0],
            &[f64::NAN, 9.0],
        );
        let mut next = Vec::new();
        chunk.write(&mut next).unwrap();
        let one = decode_rows(&next[5..]).unwrap();
        assert_eq!((one.len(), one.speeds_mps.clone()), (1, vec![3.0, 4.0]));
        write_msg(
            &mut buf,
            &WorkerMsg::Failed {
                message: "x".into(),
            },
        )
        .unwrap();
        let mut r = buf.as_slice();
        let Some(Frame::Rows(d)) = read_frame(&mut r).unwrap() else {
            panic!("rows expected")
        };
        assert_eq!(d.time_s, c.time_s);
        assert_eq!(d.speeds_mps, c.speeds_mps);
        assert!(d.commands_mps[0].is_nan());
        assert!(d.gaps_m[1].is_nan());
        assert_eq!([d.gaps_m[0], d.gaps_m[2], d.gaps_m[3]], [12.0, 11.5, 3.25]);
        assert!(matches!(
            read_frame(&mut r).unwrap(),
            Some(Frame::Msg(WorkerMsg::Failed { .. }))
        ));
        assert!(read_frame(&mut r).unwrap().is_none());
    }

    #[test]
    fn ranges_round_trip_through_a_reused_frame() {
        let steps = [[0.0, 1.0, 2.5], [0.1, -0.0, f64::MAX], [0.2, f64::NAN, 3.0]];
        let mut chunk = RangeChunk::default();
        let mut buf = Vec::new();
        chunk.write(&mut buf).unwrap();
        assert!(buf.is_empty(), "an empty chunk writes nothing");
        for r in &steps[..2] {
            chunk.push(r[0], r[1], r[2]);
        }
        chunk.write(&mut buf).unwrap();
        assert!(chunk.is_empty());
        chunk.push(steps[2][0], steps[2][1], steps[2][2]);
        chunk.write(&mut buf).unwrap();
        // The reference encoding: each value as little-endian bytes, one frame per write.
        let mut reference = Vec::new();
        for part in [&steps[..2], &steps[2..]] {
            let payload: Vec<u8> = part
                .iter()
                .flatten()
                .flat_map(|x| x.to_le_bytes())
                .collect();
            write_frame(&mut reference, KIND_RANGES, &payload).unwrap();
        }
        assert_eq!(buf, reference);
        let mut r = buf.as_slice();
        let mut got = Vec::new();
        while let Some(f) = read_frame(&mut r).unwrap() {
            let Frame::Ranges(v) = f else {
                panic!("ranges expected")
            };
            got.extend(v);
        }
        assert_eq!(got.len(), 3);
        let bits =
            |v: &[[f64; 3]]| -> Vec<u64> { v.iter().flatten().map(|x| x.to_bits()).collect() };
        assert_eq!(bits(&got), bits(&steps));
    }

    #[test]
    fn truncated_frames_are_errors() {
        let mut buf = Vec::new();
        write_frame(&mut buf, KIND_JSON, b"{\"msg\":").unwrap();
        buf.truncate(buf.len() - 2);
        let err = read_frame(&mut buf.as_slice()).unwrap_err();
        assert!(
            err.to_string().starts_with("frame of 7 bytes cut short"),
            "{err}"
        );
        let err = decode_rows(&[2, 0, 0, 0, 1, 0, 0, 0]).unwrap_err();
        assert_eq!(
            err.to_string(),
            "row chunk of 8 bytes, expected 80 for 1 records of 2 vehicles"
        );
        let err = read_frame(&mut [b'X', 0, 0, 0, 0].as_slice()).unwrap_err();
        assert_eq!(err.to_string(), "unknown frame kind 0x58");
    }
}
