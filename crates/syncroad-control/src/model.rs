//! The laws' models as validated from a scenario: the delayed drivers of eq. `chandler+`
//! ([`DelayedDriverModel`]: graph, delays, leader pinning, pre-history) and the bidirectional
//! CACC platoon of eqs. `veh-proto1/2` ([`CaccModel`], behind a [`LeaderProfile`]). The scenario
//! validates them ([`crate::scenario`]); the laws, the analyses and the registry's `protocol`
//! entry read them here, below the scenario, so that a law never depends on the file format.

use serde::{Deserialize, Serialize};

use crate::agents::{LinearAgent, Transfer};
use crate::delayed_driver::HistorySpec;
use crate::graph::Graph;

/// The leader's speed over time.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum LeaderProfile {
    /// Constant speed v_0.
    Constant {
        /// v_0 [m/s].
        speed_mps: f64,
    },
    /// Cruise at v_0, brake at `decel_mps2` from `start_s` down to `low_mps`, hold for `hold_s`,
    /// then accelerate back at `accel_mps2`.
    BrakeAndRecover {
        /// Cruise speed [m/s].
        speed_mps: f64,
        /// Start of braking [s].
        start_s: f64,
        /// Lowest speed [m/s].
        low_mps: f64,
        /// Braking deceleration (positive) [m/s²].
        decel_mps2: f64,
        /// Time at the low speed [s].
        hold_s: f64,
        /// Acceleration back to cruise [m/s²].
        accel_mps2: f64,
    },
    /// Piecewise-linear speed through `(t, v)` points, constant outside.
    Points {
        /// `[t_s, v_mps]` pairs with increasing times.
        points: Vec<[f64; 2]>,
    },
}

impl LeaderProfile {
    /// Leader speed at time `t` [m/s].
    pub fn speed_at(&self, t: f64) -> f64 {
        match self {
            LeaderProfile::Constant { speed_mps } => *speed_mps,
            LeaderProfile::BrakeAndRecover {
                speed_mps,
                start_s,
                low_mps,
                decel_mps2,
                hold_s,
                accel_mps2,
            } => {
                let t_brake = (speed_mps - low_mps) / decel_mps2;
                let t_acc = (speed_mps - low_mps) / accel_mps2;
                let t1 = start_s + t_brake;
                let t2 = t1 + hold_s;
                if t < *start_s {
                    *speed_mps
                } else if t < t1 {
                    speed_mps - decel_mps2 * (t - start_s)
                } else if t < t2 {
                    *low_mps
                } else if t < t2 + t_acc {
                    low_mps + accel_mps2 * (t - t2)
                } else {
                    *speed_mps
                }
            }
            LeaderProfile::Points { points } => {
                let first = points[0];
                let last = points[points.len() - 1];
                if t <= first[0] {
                    return first[1];
                }
                if t >= last[0] {
                    return last[1];
                }
                let k = points.partition_point(|p| p[0] <= t);
                let (a, b) = (points[k - 1], points[k]);
                a[1] + (b[1] - a[1]) * (t - a[0]) / (b[0] - a[0])
            }
        }
    }

    /// Initial (t = 0) leader speed [m/s].
    pub fn initial_speed(&self) -> f64 {
        self.speed_at(0.0)
    }
}

/// The validated delayed-driver model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DelayedDriverModel {
    /// Interaction graph `A`.
    pub graph: Graph,
    /// Delays α_i [s].
    pub delay_s: Vec<f64>,
    /// Delays in steps m_i = α_i / Δt.
    pub delay_steps: Vec<usize>,
    /// Leader speed v_0 and pinning gains b_i, if any.
    pub leader: Option<(f64, Vec<f64>)>,
    /// Pre-history convention.
    pub history: HistorySpec,
    /// How the graph was given in the scenario file, with its uniform gains (for the closed
    /// forms); a scaled copy of the model keeps the shape of the scenario it came from.
    pub shape: GraphShape,
}

impl DelayedDriverModel {
    /// The model of no vehicles: a scenario without vehicles of its own (only an inflow's,
    /// which come and go), which no law and no analysis takes.
    pub(crate) fn empty() -> Self {
        Self {
            graph: crate::graph::Graph::empty(),
            delay_s: Vec::new(),
            delay_steps: Vec::new(),
            leader: None,
            history: HistorySpec::default(),
            shape: GraphShape::Other,
        }
    }

    /// The law of this validated model (graph, delays, leader, history), seeded with the
    /// scenario's initial speeds — what every backend runs.
    pub fn law(
        &self,
        step_s: f64,
        initial_speeds_mps: &[f64],
    ) -> Result<crate::delayed_driver::DelayedDriverLaw, crate::delayed_driver::LawError> {
        crate::delayed_driver::DelayedDriverLaw::new(
            &self.graph,
            &self.delay_steps,
            step_s,
            self.leader.as_ref().map(|(_, b)| b.as_slice()),
            initial_speeds_mps,
            self.leader.as_ref().map(|(v0, _)| *v0),
            self.history,
        )
    }
}

/// The validated CACC model.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CaccModel {
    /// μ_i [1/s].
    pub mu: Vec<f64>,
    /// η_i [1/s²].
    pub eta: Vec<f64>,
    /// ν_i [1/s²] (ν_N is forced to 0: the last vehicle has no follower).
    pub nu: Vec<f64>,
    /// Desired gaps s_i [m].
    pub desired_gap_m: Vec<f64>,
    /// Lags τ_i [s].
    pub tau_s: Vec<f64>,
    /// Lengths [m].
    pub length_m: Vec<f64>,
    /// Leader speed profile.
    pub leader: LeaderProfile,
}

/// The validated linear network: a graph plus the user's linear agent per driver
/// ([`crate::agents::linear`]), `u_i = Σ_j a_ij (y_j − y_i) + b_i (y_0 − y_i)` of eqs.
/// `proto-lin`, `proto-lin+`, each agent's output its vehicle's speed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LinearModel {
    /// Interaction graph `A`.
    pub graph: Graph,
    /// One agent per driver.
    pub agents: Vec<LinearAgent>,
    /// Each agent's input delay in steps.
    pub delay_steps: Vec<usize>,
    /// Leader speed y_0 and pinning gains b_i, if any.
    pub leader: Option<(f64, Vec<f64>)>,
    /// How the graph was given.
    pub shape: GraphShape,
}

/// The validated model: a graph plus an agent per driver, of one kind.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Model {
    /// Delayed drivers (eq. `chandler+`).
    DelayedDriver(DelayedDriverModel),
    /// Bidirectional CACC platoon.
    Cacc(CaccModel),
    /// The user's linear agents on a graph.
    Linear(LinearModel),
}

impl Model {
    /// Each driver's agent as the theory sees it ([`crate::agents`]).
    pub fn transfers(&self) -> Vec<Transfer> {
        match self {
            Model::DelayedDriver(m) => m
                .delay_s
                .iter()
                .map(|&d| Transfer::delayed_integrator(d))
                .collect(),
            Model::Cacc(m) => {
                m.mu.iter()
                    .zip(&m.tau_s)
                    .map(|(&mu, &tau)| Transfer::cacc_vehicle(mu, tau))
                    .collect()
            }
            Model::Linear(m) => m.agents.iter().map(|a| a.transfer.clone()).collect(),
        }
    }

    /// The leader's speed and the pinning gains, for the kinds whose graph is given with them.
    pub fn pinning(&self) -> Option<&(f64, Vec<f64>)> {
        match self {
            Model::DelayedDriver(m) => m.leader.as_ref(),
            Model::Linear(m) => m.leader.as_ref(),
            Model::Cacc(_) => None,
        }
    }
}

/// How the interaction graph was given, with its gain where one number holds for every driver
/// it concerns: the closed forms (Chandler's condition, the uniform ring's modes) apply only
/// then.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum GraphShape {
    /// Each driver follows its predecessor on a ring.
    UnidirectionalRing {
        /// The gain K, when every driver has the same.
        gain: Option<f64>,
    },
    /// Each driver reacts to predecessor and follower on a ring.
    BidirectionalRing {
        /// The predecessor gain, when every driver has the same.
        gain_pred: Option<f64>,
        /// The follower gain, when every driver has the same.
        gain_follow: Option<f64>,
    },
    /// A chain behind vehicle 0.
    Chain {
        /// The predecessor gain of vehicles 1.., when they all have the same.
        follower_gain: Option<f64>,
    },
    /// All-to-all, explicit arcs or an explicit matrix.
    Other,
}

impl GraphShape {
    /// The shape of the graph with every gain times `c`.
    pub fn scaled(self, c: f64) -> Self {
        let k = |g: Option<f64>| g.map(|g| g * c);
        match self {
            GraphShape::UnidirectionalRing { gain } => {
                GraphShape::UnidirectionalRing { gain: k(gain) }
            }
            GraphShape::BidirectionalRing {
                gain_pred,
                gain_follow,
            } => GraphShape::BidirectionalRing {
                gain_pred: k(gain_pred),
                gain_follow: k(gain_follow),
            },
            GraphShape::Chain { follower_gain } => GraphShape::Chain {
                follower_gain: k(follower_gain),
            },
            GraphShape::Other => GraphShape::Other,
        }
    }
}

/// The scenario's own law as a run builds it: its model, the initial speeds (the delay
/// buffers' pre-history) and whether the leader vehicle is the first on the road. The
/// registry's `protocol` entry builds its law from this, carried by the run's
/// [`crate::speed_controller::LawContext`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ProtocolInput {
    /// The validated model.
    pub model: Model,
    /// Initial speeds of the law's vehicles \[m/s\] (without the leader vehicle).
    pub initial_speed_mps: Vec<f64>,
    /// The leader vehicle is index 0 of the stepped speeds.
    pub leader_vehicle: bool,
}
