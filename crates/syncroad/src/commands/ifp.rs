//! `syncroad ifp`: the IFP index of an agent `W(λ) = η(λ)/(λ ρ(λ))` (Lemma `lem.linear-pass`).

use crate::error::{InputError, Status};
use crate::stdout::outln;

/// Prints the index (text or JSON).
pub fn run(eta: &[f64], rho: &[f64], json: bool) -> anyhow::Result<Status> {
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
