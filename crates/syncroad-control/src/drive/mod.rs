//! Who drives each vehicle, as data: SUMO's car-following models with all their parameters
//! ([`car_following`]), the named drivers and their written forms ([`sumo_driver`]), and which
//! vehicles of a mixed road the law (or a damper) drives ([`Placement`]).
//!
//! Nothing here starts SUMO; the SUMO crate turns a driver into a `vType` and checks it
//! before SUMO starts.

pub mod car_following;
pub mod sumo_driver;

pub use car_following::{CarFollowing, CarFollowingError, CfModel};
pub use sumo_driver::{preset, DriverError, Preset, SumoDriver, PRESETS};
