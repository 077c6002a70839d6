//! The gap certificate's lines under `syncroad check`'s table. The computation is
//! `syncroad_control::exact::gaps`.

use std::fmt::Write as _;

use syncroad_control::exact::gaps::{GapCertificate, GapError};

/// The verdict line and the numbers behind it; `synchronizes` is the verdict of the paper's
/// conditions (the certificate itself needs only that the linear responses settle).
pub fn gap_lines(cert: &Result<Option<GapCertificate>, GapError>, synchronizes: bool) -> String {
    let regulates = matches!(cert, Ok(Some(c)) if c.safe_binding.is_some());
    let mut s = String::from(if regulates {
        "\ngap certificate (linear model; the law regulates the gaps):\n"
    } else {
        "\ngap certificate (linear model; the law couples speeds, not gaps):\n"
    });
    let c = match cert {
        Ok(Some(c)) => c,
        Ok(None) => return String::new(),
        Err(e) => {
            let _ = writeln!(s, "  not computed: {e}");
            return s;
        }
    };
    let sync = if synchronizes {
        "synchronizes"
    } else {
        "the linear gaps settle (the paper's conditions do not certify synchronization)"
    };
    if c.own_contact {
        let _ = writeln!(
            s,
            "  {sync}, but the gaps may shrink by up to {:.3} m: contact at the scenario's own perturbation ({:.3} m/s; gap of vehicle {} reaches {:.3} m at t = {:.1} s)",
            c.worst_shrinkage_m_per_mps * c.own_perturbation_mps,
            c.own_perturbation_mps,
            c.own_min_gap_vehicle,
            c.own_min_gap_m,
            c.own_min_gap_time_s
        );
    } else {
        let _ = writeln!(
            s,
            "  {sync}, and no contact for speed perturbations up to {:.4} m/s (the scenario's own: {:.3} m/s, smallest gap {:.3} m at t = {:.1} s)",
            c.safe_perturbation_mps, c.own_perturbation_mps, c.own_min_gap_m, c.own_min_gap_time_s
        );
    }
    match &c.safe_binding {
        // CACC closes a large initial gap while the perturbation acts: what a gap has left at t
        // counts, not its initial value.
        Some(b) => {
            let _ = writeln!(
                s,
                "  worst shrinkage M = sup_t max_i Σ_j |h_ij(t)| = {:.4} m per m/s (gap {}, t = {:.2} s); the safe perturbation is min over gaps and time of (desired gap + the spacing error the initial gaps leave) / Σ_j |h_ij(t)|, binding at gap {} at t = {:.2} s",
                c.worst_shrinkage_m_per_mps, c.worst_gap, c.worst_time_s, b.gap, b.time_s
            );
        }
        None => {
            let _ = writeln!(
                s,
                "  worst shrinkage M = sup_t max_i Σ_j |h_ij(t)| = {:.4} m per m/s (gap {}, t = {:.2} s); initial gaps ≥ M·ε keep perturbations ≤ ε m/s contact-free",
                c.worst_shrinkage_m_per_mps, c.worst_gap, c.worst_time_s
            );
        }
    }
    let lo = c.final_gap_m.iter().cloned().fold(f64::INFINITY, f64::min);
    let hi = c
        .final_gap_m
        .iter()
        .cloned()
        .fold(f64::NEG_INFINITY, f64::max);
    let _ = writeln!(
        s,
        "  final gaps of the scenario's own state: {lo:.3} … {hi:.3} m at {:.4} m/s",
        c.final_speed_mps
    );
    if let Some(g) = c.sampled_own_min_gap_m {
        let _ = writeln!(
            s,
            "  the runs apply the law at every step and hold it until the next: their own smallest gap is {g:.4} m (the continuous-time law's above: {:.4} m; the sampled law converges to it at first order in the step)",
            c.own_min_gap_m
        );
    }
    if let Some(r) = c.leader_step_m_per_mps {
        let _ = writeln!(
            s,
            "  a leader speed step of ε m/s moves a spacing error by up to {r:.4}·ε m (either sign)"
        );
    }
    let method = if c.leader_step_m_per_mps.is_some() {
        "exact exponential".to_string()
    } else {
        format!(
            "Richardson error ≤ {:.1e} m per m/s",
            c.integration_error_m_per_mps
        )
    };
    let _ = writeln!(
        s,
        "  integrated {:.0} s (h = {} s, {method}){}",
        c.horizon_s,
        c.step_s,
        if c.settled {
            ", every response settled"
        } else {
            ": NOT SETTLED, the sup is over this horizon only"
        }
    );
    s
}
