//! The errors a SUMO run can meet before SUMO starts: every one names the scenario field or
//! the option at fault and what would be valid.

use std::path::PathBuf;

use crate::layout::LayoutError;
use crate::net::NetError;
use syncroad_control::drive::DriverError;

/// Errors found before SUMO starts.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PrepareError {
    /// The scenario names no network.
    #[error("sumo.net is not set; the sumo backend needs a network file, e.g. \"sumo\": {{\"net\": \"{example}\"}} (relative to the scenario file)")]
    NoNet {
        /// A shipped network that fits the road type.
        example: String,
    },
    /// The network file does not exist.
    #[error("sumo.net = {path}: file not found (checked before starting SUMO)")]
    NetNotFound {
        /// The resolved path.
        path: PathBuf,
    },
    /// An input file that is not a regular file (a FIFO, a device, a folder): SUMO would read
    /// it to its end, which for a FIFO never comes.
    #[error("{field} = {path}: {what}, not a regular file: SUMO reads its input files to their end; give a file (checked before starting SUMO)")]
    NotARegularFile {
        /// The scenario field (`sumo.net`, `sumo.routes[0]`, …).
        field: String,
        /// The resolved path.
        path: PathBuf,
        /// What it is instead.
        what: &'static str,
    },
    /// A file of the user's own traffic (`sumo.routes`, `sumo.additional`) does not exist.
    #[error("{field}[{index}] = {path}: file not found (checked before starting SUMO)")]
    UserFileNotFound {
        /// The scenario field.
        field: &'static str,
        /// Its index in `sumo.routes`.
        index: usize,
        /// The resolved path.
        path: PathBuf,
    },
    /// A file of the user's own traffic is not one SUMO can run: given twice, empty, not
    /// well-formed, or naming an edge, lane, vehicle type or route that nothing defines.
    #[error("{field}[{index}] = {}: {reason} (checked before starting SUMO)", path.display())]
    UserFile {
        /// The scenario field.
        field: &'static str,
        /// Its index.
        index: usize,
        /// The resolved path.
        path: PathBuf,
        /// What is wrong and what would be valid.
        reason: String,
    },
    /// A file of the user's own traffic defines an id syncroad's vehicles use: SUMO would
    /// refuse to start ("Another vehicle with the id … exists").
    #[error("{}[{}] = {}: <{} id=\"{}\"> uses an id of syncroad's own {} ({}); rename it in your file (checked before starting SUMO)", .0.field, .0.index, .0.path.display(), .0.tag, .0.id, .0.kind, .0.ours)]
    IdClash(Box<IdClash>),
    /// `sumo.controlled` does not choose the run's vehicles, as far as the user's files show.
    #[error("sumo.controlled = {selector}: {reason} (checked before starting SUMO)")]
    Controlled {
        /// The selection, as JSON.
        selector: String,
        /// What is wrong and what would be valid.
        reason: String,
    },
    /// The network file is unusable.
    #[error(transparent)]
    Net(#[from] NetError),
    /// The vehicles do not fit.
    #[error(transparent)]
    Layout(#[from] LayoutError),
    /// An inflow the network cannot carry as given (`sumo.inflows[k]`).
    #[error("{field} = {value}: {reason} (checked before starting SUMO)")]
    Inflow {
        /// The field (`sumo.inflows[0].to`).
        field: String,
        /// Its value.
        value: String,
        /// What is wrong and what would be valid.
        reason: String,
    },
    /// A number SUMO cannot represent.
    #[error("{field} = {value}: {expected}")]
    Unrepresentable {
        /// Scenario field.
        field: &'static str,
        /// Its value.
        value: String,
        /// What SUMO accepts.
        expected: &'static str,
    },
    /// The per-vehicle drivers do not match the scenario.
    #[error("drivers: {got} given for {expected} vehicles; give one per scenario vehicle (leader excluded)")]
    Drivers {
        /// Scenario vehicles.
        expected: usize,
        /// Drivers given.
        got: usize,
    },
    /// A measurement option is out of range.
    #[error("{field} = {value}: {expected}")]
    Measure {
        /// Option.
        field: &'static str,
        /// Its value.
        value: String,
        /// What is valid.
        expected: &'static str,
    },
    /// A driver's parameters do not fit the run (e.g. `actionStepLength` off the step grid).
    #[error(transparent)]
    CarFollowing(#[from] syncroad_control::drive::CarFollowingError),
    /// A driver named in the scenario is unknown.
    #[error(transparent)]
    Driver(#[from] DriverError),
    /// A driver preset's length differs from the scenario's vehicle, so the run would not start
    /// from the scenario's positions.
    #[error("{driver}: its length {preset_m} m differs from vehicle {vehicle}'s length {length_m} m in the scenario; every run starts from the scenario's positions, so give the vehicles the preset's length (sumo.length_m)")]
    DriverLength {
        /// The driver.
        driver: String,
        /// Vehicle index.
        vehicle: usize,
        /// The preset's length \[m\].
        preset_m: f64,
        /// The scenario's length \[m\].
        length_m: f64,
    },
    /// A law of the registry (a wave damper) needs a ring.
    #[error(transparent)]
    DamperNeedsRing(#[from] syncroad_control::LawNameError),
    /// Stochastic humans follow a predecessor around a ring.
    #[error("the stochastic human drivers (human-noisy, flow-idm-noise, noisy-idm:...) drive on a ring (each vehicle follows its predecessor); scenario {scenario} is a straight road")]
    HumansNeedRing {
        /// The scenario.
        scenario: String,
    },
    /// The work folder cannot be written.
    #[error("cannot write {path}: {reason}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The OS error.
        reason: String,
    },
}

/// A user file's id that syncroad's own vehicles use ([`PrepareError::IdClash`]).
#[derive(Debug, Clone, PartialEq)]
pub struct IdClash {
    /// The scenario field.
    pub field: &'static str,
    /// Its index.
    pub index: usize,
    /// The resolved path.
    pub path: PathBuf,
    /// The element.
    pub tag: String,
    /// The id.
    pub id: String,
    /// `vehicles`, `vehicle types` or `routes`.
    pub kind: &'static str,
    /// syncroad's ids of that kind, first and last.
    pub ours: String,
}
