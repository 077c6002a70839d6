//! The child's side of [`crate::contained`]: a worker started with [`SERVE_ENV`] set builds
//! one user controller and answers one request per step (the exchange is described there).
//! Kept apart from the parent's side so that the worker program, which calls [`serve`], does
//! not depend on the supervisor that starts it.

use std::io::{BufRead, Write};

use serde::{Deserialize, Serialize};
use syncroad_control::controller::ControllerError;
use syncroad_control::user_law::{LawContext, PythonLaw};
use syncroad_control::{ControllerEnd, LawHost};

use crate::user_law::PythonHost;

/// Set in a worker's environment, it serves one controller instead of SUMO runs.
pub const SERVE_ENV: &str = "SYNCROAD_SERVE_CONTROLLER";

/// What the child is told first.
#[derive(Debug, Serialize, Deserialize)]
pub(crate) struct Setup {
    pub(crate) law: PythonLaw,
    pub(crate) context: LawContext,
}

/// The child's side: serves one controller, from the setup line to the end of its input.
/// Returns the process's exit code.
pub(crate) fn serve(input: &mut impl BufRead, out: &mut impl Write) -> u8 {
    let mut line = String::new();
    if input.read_line(&mut line).is_err() {
        return 3;
    }
    let text = |out: &mut dyn Write, tag: u8, s: &str| {
        let b = s.as_bytes();
        let _ = out.write_all(&[tag]);
        let _ = out.write_all(&(b.len() as u32).to_le_bytes());
        let _ = out.write_all(b);
        let _ = out.flush();
    };
    let setup: Setup = match serde_json::from_str(&line) {
        Ok(s) => s,
        Err(e) => {
            text(out, b'R', &format!("malformed controller setup: {e}"));
            return 3;
        }
    };
    let built = PythonHost.python(&setup.law, &setup.context);
    let mut law = match built {
        Ok(l) => l,
        Err(e) => {
            // Only the reason: the parent names the controller.
            let why = match e {
                ControllerError::Python { reason, .. } => reason,
                other => other.to_string(),
            };
            text(out, b'R', &why);
            return 2;
        }
    };
    if out.write_all(b"B").and_then(|()| out.flush()).is_err() {
        return 3;
    }
    let mut head = [0u8; 13];
    let (mut state, mut next) = (Vec::new(), Vec::new());
    loop {
        match input.read_exact(&mut head) {
            Ok(()) if head[0] == b'S' => {}
            _ => return 0,
        }
        let time_s = f64::from_le_bytes(head[1..9].try_into().expect("8 bytes"));
        let n = u32::from_le_bytes(head[9..13].try_into().expect("4 bytes")) as usize;
        state.resize(16 * n, 0u8);
        if input.read_exact(&mut state).is_err() {
            return 0;
        }
        let values: Vec<f64> = state
            .chunks_exact(8)
            .map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes")))
            .collect();
        next.resize(n, 0.0);
        law.step(time_s, &values[..n], &values[n..], &mut next);
        if let Some(ControllerEnd::Failed(why) | ControllerEnd::Stopped(why)) = law.ended() {
            text(out, b'F', &why);
            return 3;
        }
        let mut reply = Vec::with_capacity(5 + 8 * n);
        reply.push(b'C');
        reply.extend((n as u32).to_le_bytes());
        for x in &next {
            reply.extend(x.to_le_bytes());
        }
        if out.write_all(&reply).and_then(|()| out.flush()).is_err() {
            return 3;
        }
    }
}
