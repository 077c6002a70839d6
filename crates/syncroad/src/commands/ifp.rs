//! `syncroad ifp`: the IFP index of an agent `W(λ) = η(λ)/(λ ρ(λ)) · e^{−λτ}` (Lemma
//! `lem.linear-pass`; with a delay, [`syncroad_control::agents::index`]).

use crate::error::{InputError, Status};
use crate::stdout::outln;

/// Prints the index (text or JSON).
pub fn run(eta: &[f64], rho: &[f64], delay_s: f64, json: bool) -> anyhow::Result<Status> {
    if !(delay_s.is_finite() && delay_s >= 0.0) {
        return Err(InputError::new(format!(
            "--delay-s {delay_s}: the input delay must be a finite number ≥ 0 [s]"
        ))
        .into());
    }
    if delay_s > 0.0 {
        return delayed(eta, rho, delay_s, json);
    }
    let r = syncroad_control::ifp::ifp_index(eta, rho)
        .map_err(|e| InputError::caused("--eta/--rho", e))?;
    if !r.alpha.is_finite() {
        // Coefficients this far apart overflow the frequency response: no index was found,
        // and none is reported as if it had been.
        return Err(InputError::new(format!(
            "--eta {eta:?} --rho {rho:?}: the frequency response overflows (index {}); scale the coefficients to comparable magnitudes",
            r.alpha
        ))
        .into());
    }
    if json {
        outln!("{}", serde_json::to_string_pretty(&r)?);
    } else {
        let at = r
            .omega_at_inf
            .map_or("approached as ω → ∞".to_string(), |w| {
                format!("attained at ω = {w:.6} rad/s")
            });
        outln!("IFP index α = {:.9}  ({at})", r.alpha);
        outln!("W(λ) = η(λ)/(λ ρ(λ)) is IFP(α): passive with respect to y + α u (Lemma lem.linear-pass)");
    }
    Ok(Status::Success)
}

/// The index of a delayed agent: exact for a delayed integrator, a bracket otherwise.
fn delayed(eta: &[f64], rho: &[f64], delay_s: f64, json: bool) -> anyhow::Result<Status> {
    let t = syncroad_control::agents::Transfer {
        eta: eta.to_vec(),
        rho: rho.to_vec(),
        delay_s,
    };
    let r =
        syncroad_control::agents::index(&t).map_err(|e| InputError::caused("--eta/--rho", e))?;
    if json {
        let mut v = serde_json::to_value(r)?;
        v["alpha"] = r.ifp_index.into();
        v["rests_on"] = r.method.rests_on().into();
        outln!("{}", serde_json::to_string_pretty(&v)?);
    } else if r.exact {
        outln!("IFP index α = {:.9}  (exact)", r.ifp_index);
        outln!("{}", r.method.rests_on());
    } else {
        outln!(
            "IFP index α ≤ {:.9}  (rigorous upper bound; α ≥ {:.9} from a frequency sweep)",
            r.ifp_index,
            r.lower_bound
        );
        outln!("{}", r.method.rests_on());
    }
    Ok(Status::Success)
}
