//! Who drives each vehicle, as data: SUMO's car-following models with all their parameters
//! ([`car_following`]), the named drivers and their written forms ([`sumo_driver`]), which
//! vehicles of a mixed road the law (or a damper) drives ([`Placement`]), and who drives a
//! whole run ([`Drive`], in [`assignment`]).
//!
//! Nothing here starts SUMO; the SUMO crate turns a driver into a `vType` and checks it
//! before SUMO starts.

pub mod assignment;
pub mod car_following;
pub mod placement;
pub mod sumo_driver;

pub use assignment::{
    mixed_controllers, mixed_series, Drive, DriveError, MixedController, DEFAULT_MIXED_CONTROLLER,
};
pub use car_following::{CarFollowing, CarFollowingError, CfModel};
pub use placement::{automated_count, Placement};
pub use sumo_driver::{preset, DriverError, Preset, SumoDriver, DEFAULT_HUMAN, PRESETS};
