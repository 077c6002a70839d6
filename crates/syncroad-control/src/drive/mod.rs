//! Who drives each vehicle, as data: SUMO's car-following models with all their parameters
//! ([`car_following`]), the named drivers and their written forms ([`sumo_driver`]), and which
//! vehicles of a mixed road the law (or a damper) drives ([`Placement`]).
//!
//! Nothing here starts SUMO; the SUMO crate turns a driver into a `vType` and checks it
//! before SUMO starts.

pub mod car_following;
pub mod placement;
pub mod sumo_driver;

pub use car_following::{CarFollowing, CarFollowingError, CfModel};
pub use placement::{automated_count, Placement};
pub use sumo_driver::{preset, DriverError, Preset, SumoDriver, PRESETS};

/// The human driver of mixed traffic wherever none is named (a scenario's `mixed.human`,
/// `compare --mixed-driver`, a sweep's `mixed_driver`): the `human` preset, SUMO's IDM
/// calibrated so that the Sugiyama ring jams as the experiment did.
pub const DEFAULT_HUMAN: &str = "human";
