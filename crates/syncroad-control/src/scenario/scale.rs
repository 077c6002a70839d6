//! Uniform scaling of a delayed-driver scenario: every gain a_ij (and pinning gain b_i) by c,
//! every delay α_i by r. Theorem 1 and the exact boundary are both hyperbolas `c·r = const` in
//! this plane (see [`crate::exact`]), which is why sweeps and maps use these two axes.

use super::{invalid, Model, Scenario, ScenarioError};

/// A scaled scenario and how far its delays had to move to land on the step grid.
#[derive(Debug, Clone)]
pub struct Scaled {
    /// The scenario with gains `c·a_ij`, `c·b_i` and delays `k_i·Δt`, `k_i = round(r·α_i/Δt)`.
    pub scenario: Scenario,
    /// Largest |k_i·Δt − r·α_i| [s].
    pub delay_rounding_s: f64,
}

impl Scenario {
    /// Scales every gain by `gain` and every delay by `delay` (delays rounded to the step
    /// grid, since the simulation delays by whole steps). Only delayed-driver models have
    /// these gains and delays; the field names in errors are `scale.gain` and `scale.delay`.
    pub fn scaled(&self, gain: f64, delay: f64) -> Result<Scaled, ScenarioError> {
        if !(gain.is_finite() && gain > 0.0) {
            return Err(invalid("scale.gain", gain, "a finite number > 0"));
        }
        if !(delay.is_finite() && delay >= 0.0) {
            return Err(invalid("scale.delay", delay, "a finite number ≥ 0"));
        }
        let m = match &self.model {
            Model::DelayedDriver(m) => m,
            Model::Linear(l) => return Ok(self.scaled_linear(l, gain, delay)),
            Model::Cacc(_) => {
                return Err(invalid(
                    "scale",
                    "a CACC model",
                    "gain and delay scaling apply to delayed-driver and linear models (model.type = \"delayed_driver\" or \"linear\")",
                ))
            }
        };
        let mut s = m.clone();
        s.graph = m.graph.scaled(gain);
        s.shape = m.shape.scaled(gain);
        if let Some((_, b)) = s.leader.as_mut() {
            b.iter_mut().for_each(|x| *x *= gain);
        }
        let (delay_s, delay_steps, worst) = self.scaled_delays(&m.delay_s, &m.delay_steps, delay);
        (s.delay_s, s.delay_steps) = (delay_s, delay_steps);
        // The scaled delays get their buffers like the scenario's own: the same limit.
        if let Err(ScenarioError::DelayBufferTooLarge {
            vehicle,
            values,
            min_step_s,
            ..
        }) = super::validate::check_delay_buffer(&s.delay_steps, &s.delay_s, self.step_s)
        {
            return Err(invalid(
                "scale.delay",
                delay,
                format!(
                    "scales model.delay_s[{vehicle}] to {} s, which with step_s = {} s needs a delay buffer of {values:.3e} values; at most {} are allowed (a smaller scale, or step_s ≥ {min_step_s:.3e} s)",
                    s.delay_s[vehicle],
                    self.step_s,
                    super::MAX_DELAY_BUFFER
                ),
            ));
        }
        let mut scenario = self.clone();
        scenario.model = Model::DelayedDriver(s);
        Ok(Scaled {
            scenario,
            delay_rounding_s: worst,
        })
    }

    /// Delays times `delay` on the step grid: the new delays, their steps, and the largest
    /// distance a delay moved to land on the grid. A delay that lands on its own grid point
    /// keeps its value (6·0.1 is not 0.6): scales that round to the scenario's delays give the
    /// scenario itself.
    fn scaled_delays(
        &self,
        delay_s: &[f64],
        delay_steps: &[usize],
        delay: f64,
    ) -> (Vec<f64>, Vec<usize>, f64) {
        let mut worst: f64 = 0.0;
        let (mut out_s, mut out_steps) = (Vec::new(), Vec::new());
        for (&a, &k) in delay_s.iter().zip(delay_steps) {
            let exact = a * delay;
            let steps = (exact / self.step_s).round();
            out_steps.push(steps as usize);
            out_s.push(if steps as usize == k {
                a
            } else {
                steps * self.step_s
            });
            worst = worst.max((steps * self.step_s - exact).abs());
        }
        (out_s, out_steps, worst)
    }

    /// The linear agents with every `a_ij`, `b_i` times `gain` and every delay times `delay`
    /// (rounded to the step grid, as the delayed drivers').
    fn scaled_linear(&self, m: &crate::model::LinearModel, gain: f64, delay: f64) -> Scaled {
        let mut s = m.clone();
        s.graph = m.graph.scaled(gain);
        s.shape = m.shape.scaled(gain);
        if let Some((_, b)) = s.leader.as_mut() {
            b.iter_mut().for_each(|x| *x *= gain);
        }
        let delays: Vec<f64> = m.agents.iter().map(|a| a.transfer.delay_s).collect();
        let (delay_s, delay_steps, worst) = self.scaled_delays(&delays, &m.delay_steps, delay);
        for (a, d) in s.agents.iter_mut().zip(delay_s) {
            a.transfer.delay_s = d;
        }
        s.delay_steps = delay_steps;
        let mut scenario = self.clone();
        scenario.model = Model::Linear(s);
        Scaled {
            scenario,
            delay_rounding_s: worst,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ring() -> Scenario {
        Scenario::from_json(
            r#"{"name": "t", "backend": "native", "seed": 1, "step_s": 0.1, "horizon_s": 10,
                "vehicles": 4, "road": {"type": "ring", "length_m": 100},
                "model": {"type": "delayed_driver",
                          "graph": {"type": "bidirectional_ring", "gain_pred": 0.6, "gain_follow": 0.1},
                          "delay_s": [0.5, 0.6, 0.7, 0.5]},
                "initial": {"speed_mps": 8}}"#,
        )
        .unwrap()
    }

    /// 4 vehicles × (5·10⁷ + 2) buffer rows pass the 2²⁴-value limit (the scenario's own
    /// check, `(max_i m_i + 2)·N`); a scale of 10⁶ on a 0.5 s delay would otherwise allocate
    /// 1.6 GB per run.
    #[test]
    fn a_delay_scale_past_the_buffer_limit_is_refused_naming_the_scale() {
        let e = ring().scaled(1.0, 1e7).unwrap_err().to_string();
        assert!(
            e.contains("scale.delay = 10000000") && e.contains("model.delay_s[2]"),
            "{e}"
        );
        // (m + 2)·N = (10·7·10⁴ + 2)·4 < 2²⁴ passes: 10⁴ scales 0.7 s to 7000 s = 70000 steps.
        assert!(ring().scaled(1.0, 1e4).is_ok());
    }

    #[test]
    fn gains_scale_and_delays_round_to_the_grid() {
        let sc = ring();
        let s = sc.scaled(2.0, 1.25).unwrap();
        let (Model::DelayedDriver(a), Model::DelayedDriver(b)) = (&sc.model, &s.scenario.model)
        else {
            unreachable!()
        };
        assert_eq!(b.graph.adjacency_dense(), a.graph.adjacency_dense() * 2.0);
        // 1.25·(0.5, 0.6, 0.7) = (0.625, 0.75, 0.875) → 6, 8 (round half away), 9 steps.
        assert_eq!(b.delay_steps, vec![6, 8, 9, 6]);
        assert!((b.delay_s[2] - 0.9).abs() < 1e-12);
        assert!((s.delay_rounding_s - 0.05).abs() < 1e-12, "0.75 s → 0.8 s");
        let e = sc.scaled(0.0, 1.0).unwrap_err().to_string();
        assert_eq!(e, "scale.gain = 0: a finite number > 0");
    }
}
