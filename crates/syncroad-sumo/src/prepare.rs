//! One SUMO run of a validated scenario, seen from the parent: every check that can be made
//! before SUMO starts (network file, road shape, ring capacity, road length for the horizon),
//! the routes file, the supervised worker, and the results as a [`RunOutput`] comparable with
//! the native simulator's. The network file is parsed once ([`load_road`]) and shared by every
//! run of a scenario.

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;

use syncroad_control::controller::filter_params;
use syncroad_control::safety::SafetyMode;
use syncroad_control::scenario::Scenario;
use syncroad_control::start::{initial_positions, leader_start};
use syncroad_control::sumo_facts::Emissions;
use syncroad_control::{LawSpec, NamedLaw};

use crate::layout::{ring_layout, straight_layout, Layout};
pub use crate::net::loop_position;
use crate::net::{read_network_road, read_ring, read_straight, Road};
pub use crate::output::SumoRun;
use crate::protocol::{Control, Measure, ReadMode, Request};
use crate::supervisor::{run_worker, Supervision, WorkerCommand, WorkerPool};
use syncroad_control::drive::SumoDriver;

/// Tolerance between commanded and realised speed before a command counts as overridden [m/s].
pub const OVERRIDE_TOLERANCE_MPS: f64 = 1e-6;

/// Steps between two reads of SUMO's odometer with [`ReadMode::Getters`].
pub const ODOMETER_EVERY: usize = 10;

pub use crate::prepare_error::{IdClash, PrepareError};

/// The files a SUMO run writes into its work folder (`RunOptions::work_dir`): the vehicles'
/// routes, SUMO's log, the induction loop and its output, trip info, SSM and summary output,
/// the floating-car data and its replay files, where the road lies. None of
/// them may be a file the run reads (see the CLI's input check).
pub const WORK_FILES: [&str; 11] = [
    "routes.rou.xml",
    "sumo.log",
    "detectors.add.xml",
    "e1.xml",
    "tripinfo.xml",
    "ssm.xml",
    "summary.xml",
    crate::replay::FCD_FILE,
    crate::replay::REPLAY_CONFIG,
    crate::replay::REPLAY_TYPES,
    crate::replay::ROAD_FILE,
];

/// Options of a SUMO run.
#[derive(Clone)]
pub struct RunOptions {
    /// Folder for the routes file and SUMO's log.
    pub work_dir: PathBuf,
    /// How to start the worker.
    pub worker: WorkerCommand,
    /// Record every k-th step.
    pub record_every: usize,
    /// Ballistic position update (trapezoidal, as the native simulator; see the timing notes
    /// of the co-simulation step).
    pub ballistic: bool,
    /// Wall-clock limit; `None` takes `sumo.timeout_s` of the scenario.
    pub timeout: Option<Duration>,
    /// Ctrl-C flag.
    pub interrupt: Option<Arc<AtomicBool>>,
    /// How the loop reads states.
    pub read: ReadMode,
    /// Called when SUMO runs in the worker.
    pub on_start: Option<crate::supervisor::StartHook>,
    /// Called after each chunk of rows received from the worker.
    pub on_rows: Option<crate::supervisor::RowsHook>,
    /// Per scenario vehicle (the leader excluded): `Some` lets that SUMO model drive it instead
    /// of the law. Empty: the law drives every vehicle. The leader always follows its profile.
    pub drivers: Vec<Option<SumoDriver>>,
    /// SUMO-side measurements (flow, time loss, fuel, CO2, hard braking).
    pub measure: Option<MeasureOptions>,
    /// The run's warm-up \[s\] (rounded down to whole steps): SUMO's measurements and every
    /// vehicle's metrics from SUMO's summary (`all_vehicles`) are of the time after it, as the
    /// congestion metrics are.
    pub warmup_s: f64,
    /// A wave damper drives the vehicles the law would drive (rings only); `None`: the
    /// scenario's law, or the damper its `mixed.controller` names.
    pub damper: Option<NamedLaw>,
    /// Also write SUMO's floating-car data and the files that replay it (`--fcd`; the
    /// scenario's `sumo.fcd` asks for it too).
    pub fcd: bool,
    /// SUMO writes its floating-car data every this many steps (`--fcd-every`; 0 and 1:
    /// every step), and the replay steps at that interval.
    pub fcd_every: usize,
}

/// What to measure in SUMO during a run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeasureOptions {
    /// Read fuel and CO2 every this many steps (≥ 1).
    pub emission_every: usize,
    /// Also write SUMO's trip info with emission totals (`tripinfo.xml` in the work folder).
    pub tripinfo: bool,
    /// Also log SUMO's surrogate safety measures (`ssm.xml` in the work folder) and report
    /// time headway, gaps, TTC, DRAC and the safe-speed label in the record.
    pub ssm: bool,
    /// The emission sums to read ([`Emissions::ALL`] for a full record).
    pub emissions: Emissions,
}

impl RunOptions {
    /// Defaults: every step recorded, ballistic update, the scenario's law, its timeout.
    pub fn new(work_dir: impl Into<PathBuf>, worker: WorkerCommand) -> Self {
        Self {
            work_dir: work_dir.into(),
            worker,
            record_every: 1,
            ballistic: true,
            timeout: None,
            interrupt: None,
            read: ReadMode::Direct,
            on_start: None,
            on_rows: None,
            drivers: Vec::new(),
            measure: None,
            warmup_s: 0.0,
            damper: None,
            fcd: false,
            fcd_every: 1,
        }
    }
}

/// The network file of a scenario (resolved when the scenario was validated), checked to exist.
pub fn net_path(scenario: &Scenario) -> Result<PathBuf, PrepareError> {
    let Some(net) = scenario.sumo().net() else {
        return Err(PrepareError::NoNet {
            example: if scenario.is_ring() {
                "../sumo-nets/sugiyama-ring.net.xml".into()
            } else {
                "../sumo-nets/straight-20km.net.xml".into()
            },
        });
    };
    if let Some(what) = crate::input_file::not_regular(net) {
        return Err(PrepareError::NotARegularFile {
            field: "sumo.net".into(),
            path: net.to_path_buf(),
            what,
        });
    }
    if !net.is_file() {
        return Err(PrepareError::NetNotFound {
            path: net.to_path_buf(),
        });
    }
    Ok(net.to_path_buf())
}

/// Numbers SUMO itself restricts: its clock counts whole milliseconds and `--seed` is a
/// 32-bit signed integer.
pub fn check_sumo_numbers(scenario: &Scenario) -> Result<(), PrepareError> {
    let ms = scenario.step_s() * 1000.0;
    if (ms - ms.round()).abs() > 1e-9 * ms.max(1.0) || ms.round() < 1.0 {
        return Err(PrepareError::Unrepresentable {
            field: "step_s",
            value: scenario.step_s().to_string(),
            expected: "SUMO's clock counts whole milliseconds: use a multiple of 0.001 s",
        });
    }
    if scenario.seed() > i32::MAX as u64 {
        return Err(PrepareError::Unrepresentable {
            field: "seed",
            value: scenario.seed().to_string(),
            expected: "SUMO's --seed takes 0 ..= 2147483647",
        });
    }
    Ok(())
}

/// Reads the scenario's network file once (every pre-start check of the road).
pub fn load_road(scenario: &Scenario) -> Result<Road, PrepareError> {
    let net = net_path(scenario)?;
    if scenario.road().is_network() {
        let vclass = scenario.sumo().vehicle_type().vclass;
        return Ok(read_network_road(&net, scenario.road(), vclass)?);
    }
    Ok(if scenario.is_ring() {
        read_ring(&net)?
    } else {
        read_straight(&net)?
    })
}

/// The layout of a scenario on its road (capacity and road length for the horizon).
pub fn layout_for(scenario: &Scenario, road: &Road) -> Result<Layout, PrepareError> {
    let vtype = *scenario.sumo().vehicle_type();
    let horizon = scenario.horizon_s();
    let layout = if scenario.is_ring() {
        ring_layout(
            road,
            vtype,
            scenario.length_m(),
            scenario.initial_gap_m(),
            scenario.initial_speed_mps(),
            horizon,
        )?
    } else {
        let dt = scenario.step_s();
        let travel = |f: &dyn Fn(f64) -> f64| -> f64 {
            (0..scenario.steps())
                .map(|k| 0.5 * dt * (f(k as f64 * dt) + f((k + 1) as f64 * dt)))
                .sum()
        };
        let start = leader_start(scenario);
        let leader = start.map(|(q0, _)| {
            let dist = travel(&|t| scenario.leader_speed_at(t).unwrap_or(0.0));
            (q0, scenario.length_m()[0], dist)
        });
        let q = initial_positions(scenario, start.map(|l| l.0));
        straight_layout(
            road,
            vtype,
            scenario.length_m(),
            &q,
            scenario.initial_speed_mps(),
            leader,
            start.map_or(0.0, |l| l.1),
            horizon,
        )?
    };
    Ok(layout)
}

/// Builds the worker request of a scenario on its road (writes the routes file into
/// `opts.work_dir`).
pub(crate) fn prepare(
    scenario: &Scenario,
    road: &Road,
    opts: &RunOptions,
) -> Result<Request, PrepareError> {
    prepare_with(scenario, road, opts, true)
}

/// Every check [`Prepared::new`] makes before SUMO starts (numbers, road layout, drivers and
/// their step-dependent values, damper, measurement options), without writing a file: a
/// sweep runs it on every point before any point runs.
pub fn check_run(scenario: &Scenario, road: &Road, opts: &RunOptions) -> Result<(), PrepareError> {
    prepare_with(scenario, road, opts, false).map(|_| ())
}

fn prepare_with(
    scenario: &Scenario,
    road: &Road,
    opts: &RunOptions,
    write: bool,
) -> Result<Request, PrepareError> {
    check_sumo_numbers(scenario)?;
    check_warmup(scenario, opts)?;
    let mut layout = layout_for(scenario, road)?;
    let io = |path: &Path, e: std::io::Error| PrepareError::Io {
        path: path.to_path_buf(),
        reason: e.to_string(),
    };
    let (drivers, damper) = drivers_on(scenario, opts, &mut layout)?;
    let adopt = scenario.sumo().controlled();
    let sumo_driven = layout
        .vehicles
        .iter()
        .filter(|v| v.driver.is_some())
        .count();
    let law_driven = layout.vehicles.len() - sumo_driven - usize::from(layout.leader_vehicle);
    // The safety layer under the law: the scenario's, or SUMO's checks when other traffic
    // shares the road or the network has traffic lights (syncroad_control::safety).
    let signals = crate::net::has_traffic_lights(&layout.road.path);
    // syncroad's own stochastic humans, which the bridge computes (their layout vehicles carry
    // no SUMO driver), beside vehicles of the law: automated cars among humans.
    let humans = drivers.iter().flatten().any(|d| d.commanded_by_bridge())
        && drivers.iter().any(Option::is_none);
    let safety = scenario.safety_for(sumo_driven > 0 || signals, humans);
    let speed_mode = safety.speed_mode();
    let measure = match &opts.measure {
        None => None,
        Some(m) => Some(measure_of(m, scenario, opts, &layout, write)?),
    };
    let routes_file = if write {
        layout
            .write_routes(&opts.work_dir, adopt.is_none())
            .map_err(|e| io(&opts.work_dir, e))?
    } else {
        opts.work_dir.join("routes.rou.xml")
    };
    // The leader vehicle, when there is one, always follows its profile through the law.
    let control = if law_driven == 0 && sumo_driven > 0 && !layout.leader_vehicle {
        Control::SumoModel
    } else {
        let law = law_of(scenario, &layout, &drivers, damper, (safety, signals))?;
        Control::Law { law: Box::new(law) }
    };
    let (mut extra_routes, extra_additional) =
        user_traffic(scenario, &layout, &drivers, opts, write)?;
    let guest = crate::inflows::GuestType::of(&layout);
    extra_routes.extend(crate::inflows::routes_file(
        scenario,
        &layout.road,
        &guest,
        &opts.work_dir,
        write,
    )?);
    let guests = crate::inflows::guests(scenario, &guest)?;
    let other_traffic = scenario.sumo().other_traffic();
    let fcd = opts.fcd || scenario.sumo().fcd();
    let fcd_every = opts.fcd_every.max(1);
    if write {
        let sources = [
            std::slice::from_ref(&routes_file),
            extra_routes.as_slice(),
            extra_additional.as_slice(),
        ]
        .concat();
        let replay = fcd.then_some(fcd_every);
        write_watch_files(scenario, &layout, &opts.work_dir, replay, &sources)
            .map_err(|e| io(&opts.work_dir, e))?;
    }
    Ok(Request {
        layout,
        routes_file,
        log_file: opts.work_dir.join("sumo.log"),
        step_s: scenario.step_s(),
        steps: scenario.steps(),
        seed: scenario.seed(),
        ballistic: opts.ballistic,
        control,
        speed_mode,
        safety,
        measure,
        record_every: opts.record_every.max(1),
        chunk_records: chunk_records(scenario.vehicles()),
        override_tolerance_mps: OVERRIDE_TOLERANCE_MPS,
        read: opts.read,
        odometer_every: ODOMETER_EVERY,
        // Other traffic may change lanes into the controlled lane, merge into it at a junction
        // or be inserted on it: the law's graph is SUMO's.
        sense_graph: other_traffic,
        // The metrics of every vehicle, when there are others than syncroad's.
        summary_file: other_traffic.then(|| opts.work_dir.join("summary.xml")),
        warmup_s: warmup_steps(opts, scenario) as f64 * scenario.step_s(),
        fcd_file: fcd.then(|| opts.work_dir.join(crate::replay::FCD_FILE)),
        fcd_every,
        extra_routes,
        extra_additional,
        adopt: adopt.cloned(),
        guests,
    })
}

/// The warm-up (`--warmup-s`) lies within the run.
fn check_warmup(scenario: &Scenario, opts: &RunOptions) -> Result<(), PrepareError> {
    let w = opts.warmup_s;
    if !(w.is_finite() && w >= 0.0 && w < scenario.horizon_s()) {
        return Err(PrepareError::Measure {
            field: "--warmup-s",
            value: w.to_string(),
            expected: "must be ≥ 0 and shorter than the horizon",
        });
    }
    Ok(())
}

/// Who drives each vehicle of the layout ([`drivers_of`]), put on it: SUMO's drivers on
/// their vehicles, the stochastic humans taken off again (the bridge commands them, so SUMO
/// sees law-driven vehicles), and the road each of them and the damper or the user's Rust law
/// needs checked. Returns the drivers and the damper.
fn drivers_on(
    scenario: &Scenario,
    opts: &RunOptions,
    layout: &mut Layout,
) -> Result<(Vec<Option<SumoDriver>>, Option<NamedLaw>), PrepareError> {
    let (drivers, damper) = drivers_of(scenario, opts)?;
    assign_drivers(layout, &drivers, scenario.step_s())?;
    let mut has_humans = false;
    for dep in &mut layout.vehicles {
        if dep
            .driver
            .as_ref()
            .is_some_and(SumoDriver::commanded_by_bridge)
        {
            dep.driver = None;
            has_humans = true;
        }
    }
    if has_humans && !layout.road.ring {
        return Err(PrepareError::HumansNeedRing {
            scenario: scenario.name().to_string(),
        });
    }
    let user = match scenario.controller() {
        Some(syncroad_control::UserLaw::Rust(r)) => Some(r),
        _ => None,
    };
    for d in damper.iter().chain(user) {
        d.require_road(layout.road.ring, &format!("scenario {}", scenario.name()))?;
    }
    Ok((drivers, damper))
}

/// The run's warm-up in whole steps (rounded down).
fn warmup_steps(opts: &RunOptions, scenario: &Scenario) -> usize {
    (opts.warmup_s / scenario.step_s() + 1e-9).floor() as usize
}

/// The user's own traffic (`sumo.routes`, `sumo.additional`), checked before SUMO starts (the
/// files exist and SUMO can run them, no id of syncroad's own, the vehicles `sumo.controlled`
/// chooses), with the additional files' outputs redirected into the run's folder: the route
/// and additional files to give SUMO.
fn user_traffic(
    scenario: &Scenario,
    layout: &Layout,
    drivers: &[Option<SumoDriver>],
    opts: &RunOptions,
    write: bool,
) -> Result<(Vec<PathBuf>, Vec<PathBuf>), PrepareError> {
    let adopt = scenario.sumo().controlled();
    let routes = user_files("sumo.routes", scenario.sumo().routes())?;
    let additional = user_files("sumo.additional", scenario.sumo().additional())?;
    let user: Vec<crate::user_files::UserFile<'_>> = [
        ("sumo.routes", routes.as_slice()),
        ("sumo.additional", additional.as_slice()),
    ]
    .into_iter()
    .flat_map(|(field, files)| {
        files
            .iter()
            .enumerate()
            .map(move |(index, path)| crate::user_files::UserFile { field, index, path })
    })
    .collect();
    let ours = layout.routes_xml_with(adopt.is_none());
    crate::user_files::check(&layout.road.path, &ours, &user)?;
    if scenario.sumo().other_traffic() {
        no_clashing_ids(&ours, "sumo.routes", &routes)?;
        no_clashing_ids(&ours, "sumo.additional", &additional)?;
    }
    if let Some(sel) = adopt {
        let files = [routes.as_slice(), additional.as_slice()].concat();
        crate::controlled::check_run(sel, drivers, layout, &files)?;
    }
    // What the user's additional files write goes into this run's folder.
    let additional = crate::outputs::redirect(&additional, &opts.work_dir, write)?;
    Ok((routes, additional))
}

/// The files for watching the run again, in its work folder: where its road lies, and with
/// `fcd` (its interval in steps) the replay of SUMO's floating-car data (vehicle types read
/// from `type_sources`). An earlier run's that this one does not write are removed (the folder
/// is ours).
fn write_watch_files(
    scenario: &Scenario,
    layout: &Layout,
    work_dir: &Path,
    fcd: Option<usize>,
    type_sources: &[PathBuf],
) -> std::io::Result<()> {
    let adopt = scenario.sumo().controlled();
    crate::replay::remove_stale(work_dir, fcd.is_some(), adopt.is_none())?;
    if adopt.is_none() {
        crate::replay::write_road_trace(work_dir, layout)?;
    }
    if let Some(every) = fcd {
        crate::replay::write_replay_files(
            work_dir,
            &layout.road.path,
            type_sources,
            scenario.step_s(),
            every,
            scenario.horizon_s(),
        )?;
    }
    Ok(())
}

/// The user's own files of `field` (`sumo.routes`, `sumo.additional`), checked to exist
/// before SUMO starts.
fn user_files(field: &'static str, files: &[PathBuf]) -> Result<Vec<PathBuf>, PrepareError> {
    for (i, p) in files.iter().enumerate() {
        if let Some(what) = crate::input_file::not_regular(p) {
            return Err(PrepareError::NotARegularFile {
                field: format!("{field}[{i}]"),
                path: p.clone(),
                what,
            });
        }
        if !p.is_file() {
            return Err(PrepareError::UserFileNotFound {
                field,
                index: i,
                path: p.clone(),
            });
        }
    }
    Ok(files.to_vec())
}

/// Largest user file whose ids are checked before SUMO starts (a parsed document takes several
/// times its size in memory; SUMO streams larger demand files and reports a clash itself).
const CLASH_CHECK_MAX_BYTES: u64 = 64 << 20;

/// Refuses a user file of `field` that defines a vehicle, vehicle type or route with an id of
/// syncroad's own (read from `ours`, the routes file syncroad writes). A file that is not XML,
/// or too large to read whole here ([`CLASH_CHECK_MAX_BYTES`]), is left to SUMO, whose
/// message names the id.
fn no_clashing_ids(ours: &str, field: &'static str, files: &[PathBuf]) -> Result<(), PrepareError> {
    const KINDS: [(&str, &[&str]); 3] = [
        ("vehicles", &["vehicle", "trip"]),
        ("vehicle types", &["vType"]),
        ("routes", &["route"]),
    ];
    let Ok(doc) = roxmltree::Document::parse(ours) else {
        return Ok(());
    };
    let ids_of = |tags: &[&str]| -> Vec<String> {
        doc.descendants()
            .filter(|n| tags.contains(&n.tag_name().name()))
            .filter_map(|n| n.attribute("id").map(str::to_string))
            .collect()
    };
    let ours: Vec<(&str, &[&str], Vec<String>)> = KINDS
        .iter()
        .map(|&(k, tags)| (k, tags, ids_of(tags)))
        .collect();
    for (index, path) in files.iter().enumerate() {
        let Ok(Some(text)) = crate::input_file::read_text(path, Some(CLASH_CHECK_MAX_BYTES)) else {
            continue;
        };
        let Ok(user) = roxmltree::Document::parse(&text) else {
            continue;
        };
        for n in user.descendants().filter(|n| n.is_element()) {
            let (Some(id), tag) = (n.attribute("id"), n.tag_name().name()) else {
                continue;
            };
            for (kind, tags, ids) in &ours {
                if tags.contains(&tag) && ids.iter().any(|o| o == id) {
                    return Err(PrepareError::IdClash(Box::new(IdClash {
                        field,
                        index,
                        path: path.clone(),
                        tag: tag.to_string(),
                        id: id.to_string(),
                        kind,
                        ours: match ids.as_slice() {
                            [one] => one.clone(),
                            [first, .., last] => format!("{first} … {last}"),
                            [] => String::new(),
                        },
                    })));
                }
            }
        }
    }
    Ok(())
}

/// Puts each SUMO driver of `drivers` (one per scenario vehicle; empty: the law everywhere)
/// on its vehicle of `layout`, checking lengths and the step-dependent values.
fn assign_drivers(
    layout: &mut Layout,
    drivers: &[Option<SumoDriver>],
    step_s: f64,
) -> Result<(), PrepareError> {
    if drivers.is_empty() {
        return Ok(());
    }
    let k0 = usize::from(layout.leader_vehicle);
    if drivers.len() != layout.vehicles.len() - k0 {
        return Err(PrepareError::Drivers {
            expected: layout.vehicles.len() - k0,
            got: drivers.len(),
        });
    }
    for (i, (dep, d)) in layout.vehicles[k0..].iter_mut().zip(drivers).enumerate() {
        if let Some(&preset_m) = d
            .as_ref()
            .and_then(|d| d.car_following().params.get("length").copied())
            .as_ref()
        {
            if preset_m != dep.length_m {
                return Err(PrepareError::DriverLength {
                    driver: d.as_ref().map(|d| d.to_string()).unwrap_or_default(),
                    vehicle: i,
                    preset_m,
                    length_m: dep.length_m,
                });
            }
        }
        if let Some(d) = d {
            // Every value was checked when the driver was named; the step only now.
            d.car_following()
                .validate(&format!("driver {d} of vehicle {i}"), step_s)
                .map_err(PrepareError::CarFollowing)?;
        }
        dep.driver = d.clone();
    }
    Ok(())
}

/// The SUMO-side measurements of `m`: checked, with the induction loop's file written into
/// the work folder when `write`.
fn measure_of(
    m: &MeasureOptions,
    scenario: &Scenario,
    opts: &RunOptions,
    layout: &Layout,
    write: bool,
) -> Result<Measure, PrepareError> {
    let io = |path: &Path, e: std::io::Error| PrepareError::Io {
        path: path.to_path_buf(),
        reason: e.to_string(),
    };
    if m.emission_every == 0 {
        return Err(PrepareError::Measure {
            field: "--emission-every",
            value: "0".into(),
            expected: "must be ≥ 1 (1 = read fuel and CO2 every step)",
        });
    }
    if write {
        std::fs::create_dir_all(&opts.work_dir).map_err(|e| io(&opts.work_dir, e))?;
    }
    let detector_file = match loop_position(&layout.road) {
        Some(_) if !write => None,
        Some((lane, pos, _)) => {
            let f = opts.work_dir.join("detectors.add.xml");
            // SUMO resolves `file` relative to the additional file itself.
            let text = format!(
                        "<additional>\n    <inductionLoop id=\"loop0\" lane=\"{lane}\" pos=\"{pos}\" period=\"86400\" file=\"e1.xml\"/>\n</additional>\n"
                    );
            std::fs::write(&f, text).map_err(|e| io(&f, e))?;
            Some(f)
        }
        None => None,
    };
    Ok(Measure {
        warmup_steps: warmup_steps(opts, scenario),
        emission_every: m.emission_every,
        detector_file,
        tripinfo_file: m.tripinfo.then(|| opts.work_dir.join("tripinfo.xml")),
        ssm_file: m.ssm.then(|| opts.work_dir.join("ssm.xml")),
        emissions: m.emissions,
    })
}

/// The law of a run on the road SUMO will drive: the scenario's, on the layout (its ring
/// length, vehicles and speed limit), under the safety layer, on a network with or without
/// traffic lights, driven by `drivers` and `damper` as both backends resolve them
/// ([`LawSpec::driven_by`]).
fn law_of(
    scenario: &Scenario,
    layout: &Layout,
    drivers: &[Option<SumoDriver>],
    damper: Option<NamedLaw>,
    (safety, signals): (SafetyMode, bool),
) -> Result<LawSpec, PrepareError> {
    let mut law = LawSpec::of(scenario);
    let vt = &layout.vtype;
    let limit = Some(layout.road.speed_limit_mps()).filter(|l| l.is_finite());
    law.safety = filter_params(safety, vt.min_gap_m, vt.decel_mps2, limit);
    let c = &mut law.context;
    if let Some(p) = c.protocol.as_mut() {
        p.leader_vehicle = layout.leader_vehicle;
    }
    c.ids = layout.vehicles.iter().map(|v| v.id.clone()).collect();
    c.length_m = layout.vehicles.iter().map(|v| v.length_m).collect();
    c.ring_length_m = layout.road.ring.then(|| layout.road.length_m());
    c.controlled = vec![true; layout.vehicles.len()];
    c.accel_mps2 = layout.vtype.accel_mps2;
    c.decel_mps2 = layout.vtype.decel_mps2;
    c.speed_limit_mps = limit;
    c.signals = signals;
    law.driven_by(drivers, damper, scenario.seed())
        .map_err(|_| PrepareError::HumansNeedRing {
            scenario: scenario.name().to_string(),
        })
}

/// Who drives each scenario vehicle and which damper commands the law's vehicles
/// ([`syncroad_control::controller::drivers_for`]: the run options when they name drivers,
/// else the scenario's `mixed` section, else the law alone).
pub fn drivers_of(
    scenario: &Scenario,
    opts: &RunOptions,
) -> Result<(Vec<Option<SumoDriver>>, Option<NamedLaw>), PrepareError> {
    Ok(syncroad_control::controller::drivers_for(
        scenario,
        &opts.drivers,
        opts.damper.as_ref(),
    )?)
}

/// Records per chunk: about 256 KiB of rows, at least one record.
pub fn chunk_records(n: usize) -> usize {
    ((256 * 1024) / (8 * (1 + 3 * (n + 1)))).max(1)
}

/// A SUMO run checked and ready: the worker request (routes file written) and its supervision.
#[derive(Debug)]
pub struct Prepared {
    request: Request,
    supervision: Supervision,
    worker: WorkerCommand,
}

impl Prepared {
    /// Every check that can be made before SUMO starts, on a road read once with
    /// [`load_road`]; errors here mean SUMO never started.
    pub fn new(scenario: &Scenario, road: &Road, opts: &RunOptions) -> Result<Self, PrepareError> {
        let request = prepare(scenario, road, opts)?;
        let timeout = Some(opts.timeout.unwrap_or(scenario.sumo().timeout()));
        Ok(Self {
            request,
            supervision: Supervision {
                timeout,
                interrupt: opts.interrupt.clone(),
                on_start: opts.on_start.clone(),
                on_rows: opts.on_rows.clone(),
            },
            worker: opts.worker.clone(),
        })
    }

    /// The worker request.
    pub fn request(&self) -> &Request {
        &self.request
    }

    /// The worker request, to change before [`Prepared::run`] (tests and the benchmark).
    pub fn request_mut(&mut self) -> &mut Request {
        &mut self.request
    }

    /// Runs the request on a long-lived worker of `pool` (started or replaced as needed):
    /// the same run as [`Prepared::run`] without a process and Python start per run.
    pub fn run_in(self, pool: &WorkerPool) -> SumoRun {
        let worker = pool.run(&self.request, &self.supervision);
        SumoRun {
            request: self.request,
            worker,
        }
    }

    /// Runs the request in one supervised worker. Rows are in the result whatever the end of
    /// the run.
    pub fn run(self) -> SumoRun {
        let worker = run_worker(&self.worker, &self.request, &self.supervision);
        SumoRun {
            request: self.request,
            worker,
        }
    }
}

/// Runs a scenario in SUMO: reads its network, checks, then one supervised worker.
pub fn run_scenario(scenario: &Scenario, opts: &RunOptions) -> Result<SumoRun, PrepareError> {
    let road = load_road(scenario)?;
    Ok(Prepared::new(scenario, &road, opts)?.run())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn prepare_errors_name_the_field() {
        let e = PrepareError::NoNet {
            example: "../sumo-nets/sugiyama-ring.net.xml".into(),
        };
        assert!(e
            .to_string()
            .starts_with("sumo.net is not set; the sumo backend needs a network file"));
    }
}
