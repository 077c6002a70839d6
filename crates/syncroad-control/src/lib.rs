//! # syncroad-control
//!
//! Velocity synchronization of vehicles after Proskurnikov & Mazo, "Simple synchronization
//! protocols for heterogeneous networks: beyond passivity". Pure Rust, no Python.
//!
//! Layers, bottom up:
//! * [`graph`] — weighted directed interaction graphs `G[A]`, degrees, connectivity, Laplacian;
//! * [`scenario`] — scenario files and their validation;
//! * [`delayed_driver`], [`cacc`] — the laws (eq. `chandler+`; eqs. `veh-proto1/2`), one step
//!   at a time, usable by any backend;
//! * [`follower_stopper`], [`pi_saturation`] — the field's wave dampers of Stern et al. (2018)
//!   as references, with [`actuation`] turning their command velocity into the next speed,
//!   and [`damper`] running them on a ring as a controller;
//! * [`flow_dampers`] — the same two dampers as Flow's master code computes them;
//! * [`registry`] — the one table of laws that drive in place of the model's: the dampers,
//!   [`constant_speed`], the bilateral control model ([`bcm`]), a linear ACC ([`lacc`]),
//!   and the laws a program registers; each is a [`LawEntry`];
//! * [`theory`], [`ifp`], [`poly`] — the paper's sufficient conditions and the IFP index;
//! * [`exact`] — exact stability: rightmost characteristic roots, critical gains, CACC modes
//!   and string stability, to show how conservative the sufficient conditions are;
//! * [`drive`] — who drives each vehicle as data: SUMO's car-following models and their
//!   parameters, the named drivers (one table), the placement of automated vehicles;
//! * [`noisy_idm`] — stochastic human drivers (IDM with Flow's or a step-consistent noise),
//!   computed by the bridge on either backend;
//! * [`controller`] — the one law object both backends step; [`sensed`] — its graph as SUMO
//!   sees it each step, when other traffic shares the road; [`user_law`] — the user's own
//!   law as data (a Python class, built by a [`LawHost`] of a crate that embeds Python, or a
//!   Rust law of the program's [`registry`]); [`user_text`] — the user's text (an
//!   exception, a worker's output) escaped, set off and cut on its way to a message;
//! * [`safety`] — the safety layer between every law and the command (`off`, SUMO's checks,
//!   or syncroad's safe-speed filter);
//! * [`native`] — the fixed-step simulator; [`stop`] — why a run stopped; [`observer`] — the
//!   one trait of what watches a loop (natively and in SUMO); [`collisions`] — vehicles the
//!   native simulator drove through each other or backwards;
//! * [`metrics`], [`congestion`], [`margins`] — the synchronization verdict, congestion
//!   measures and safety margins (time headway, gaps, SUMO's surrogate safety measures);
//! * [`outcome`], [`record`] — one run, whatever ran it: output → outcome → the `metrics.json`
//!   record (its derived schema in `record/`), with [`sumo_facts`], what a SUMO run reports.
#![warn(missing_docs)]
// Numerical loops index several arrays at once; an index reads clearer than zipped iterators.
#![allow(clippy::needless_range_loop)]

pub mod actuation;
pub mod agents;
pub mod bcm;
pub mod cacc;
pub mod collisions;
pub mod congestion;
pub mod constant_speed;
pub mod controller;
pub mod damper;
pub mod delayed_driver;
pub mod delayed_follower;
pub mod drive;
pub mod exact;
pub mod fingerprint;
pub mod flow_dampers;
pub mod follower_stopper;
pub mod graph;
pub mod ifp;
pub mod lacc;
pub mod lti_network;
pub mod margins;
pub mod metrics;
pub mod model;
pub mod native;
pub mod noisy_idm;
pub mod observer;
pub mod outcome;
pub mod pi_saturation;
pub mod poly;
pub mod protocol_law;
pub mod record;
pub mod registry;
pub mod rng;
pub mod road;
pub mod safety;
pub mod scenario;
pub mod sensed;
pub mod speed_controller;
pub mod start;
pub mod stop;
pub mod string_measured;
pub mod sumo_facts;
pub mod theory;
pub mod trajectory;
pub mod user_law;
pub mod user_text;

pub use actuation::{AccelLimits, ActuationError};
pub use cacc::{CaccLaw, PlatoonView, PowertrainLag};
pub use controller::LawHost;
pub use controller::{controller_for, controller_for_in, LawSpec, SpeedController};
pub use delayed_driver::DelayedDriverLaw;
pub use drive::{CarFollowing, CfModel, SumoDriver};
pub use follower_stopper::{
    follower_stopper_command_mps, FollowerStopper, FollowerStopperError, FollowerStopperParams,
};
pub use graph::{Arc, Graph};
pub use metrics::{sync_metrics, SyncMetrics, Verdict, VerdictThresholds};
pub use native::{simulate, simulate_controller, simulate_with, NativeOptions, NativeRun};
pub use noisy_idm::{HumanSetup, IdmParams, NoiseForm, NoisyIdm};
pub use outcome::{evaluate, EvalOptions, Outcome, RunOutput};
pub use pi_saturation::{
    pi_saturation_command_mps, PiSaturation, PiSaturationError, PiSaturationParams,
};
pub use record::{RunRecord, SumoFacts};
pub use registry::{LawNameError, NamedLaw, PROTOCOL};
pub use scenario::{Scenario, ScenarioError, ScenarioFile};
pub use speed_controller::ControllerEnd;
pub use speed_controller::{LawContext, LawEntry};
pub use stop::StopReason;
pub use trajectory::Trajectory;
pub use user_law::{PythonLaw, UserLaw};
