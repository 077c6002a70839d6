//! `syncroad replay`: a finished SUMO run played back in sumo-gui from SUMO's own
//! floating-car data (`sumo/fcd.xml`) through SUMO's fcd-replay device, with the files the run
//! wrote beside it (`sumo/replay.sumocfg`, `sumo/replay.types.xml`) and a view that colours
//! vehicles by speed on the run's own scale (`sumo/replay.view.xml`, written here).

use std::io::{Read, Seek, SeekFrom};
use std::path::Path;
use std::process::Command;

use syncroad_control::scenario::Backend;
use syncroad_sumo::{FCD_FILE, REPLAY_CONFIG};

use crate::animate::{scene, speed_scale};
use crate::error::{InputError, Status};
use crate::output::{self, SUMO_WORK_DIR};
use crate::stdout::outln;

/// The view settings `replay` writes into the run's `sumo/` folder.
pub const VIEW_FILE: &str = "replay.view.xml";

/// sumo-gui's colouring of vehicles "by speed" (the index of that scheme in its vehicle
/// colour schemes, SUMO 1.28).
const BY_SPEED: u32 = 8;

/// `syncroad replay`.
pub fn run(dir: &Path, snapshot: Option<&Path>, at_s: f64, print: bool) -> anyhow::Result<Status> {
    let record = scene::read_record(dir)?;
    if record.backend == Backend::Native {
        return Err(InputError::new(format!(
            "{}: a native run; replay plays SUMO's own record of a SUMO run back, and a native run has none — run the scenario on SUMO with --fcd (`syncroad run SCENARIO --fcd --out DIR`, its \"backend\" \"sumo\"), or animate this run: `syncroad animate {}`",
            dir.display(),
            dir.display()
        ))
        .into());
    }
    let work = dir.join(SUMO_WORK_DIR);
    let (cfg, fcd) = (work.join(REPLAY_CONFIG), work.join(FCD_FILE));
    if !fcd.is_file() || !cfg.is_file() {
        return Err(InputError::new(format!(
            "{}: has no SUMO floating-car data ({} is missing): the run was made without --fcd; run it again with --fcd (or \"sumo\": {{\"fcd\": true}} in the scenario)",
            dir.display(),
            fcd.display()
        ))
        .into());
    }
    check_complete(&fcd)?;
    if !(at_s.is_finite() && at_s >= 0.0 && at_s <= record.horizon_s) {
        return Err(InputError::new(format!(
            "--at-s = {at_s}: the snapshot's time must lie in the run, 0 … {} s",
            record.horizon_s
        ))
        .into());
    }
    let snapshot = match snapshot {
        Some(p) => {
            output::check_file_target("--snapshot", p)?;
            Some(std::path::absolute(p)?)
        }
        None => None,
    };
    let rows = scene::read_rows(dir, record.vehicles)?;
    let (vmin, vmax) = speed_scale(rows.speed_mps.iter().copied());
    let view = work.join(VIEW_FILE);
    output::write_text(&view, &view_settings(vmin, vmax, snapshot.as_deref(), at_s))?;
    let (gui, home) = syncroad_sumo::sumo_program("sumo-gui")
        .map_err(|e| InputError::caused("replay needs sumo-gui", e))?;
    let mut args: Vec<String> = vec![
        "-c".into(),
        cfg.display().to_string(),
        "--gui-settings-file".into(),
        view.display().to_string(),
        "--window-size".into(),
        "900,900".into(),
    ];
    if snapshot.is_some() {
        // Start at once, take the picture, quit a step after it.
        let end = at_s + 2.0 * record.step_s;
        args.extend(["-S".into(), "-Q".into(), "--end".into(), format!("{end}")]);
    }
    let display =
        std::env::var_os("DISPLAY").is_some() || std::env::var_os("WAYLAND_DISPLAY").is_some();
    let line = shlex::try_join(
        std::iter::once(gui.to_string_lossy().as_ref()).chain(args.iter().map(String::as_str)),
    )
    .unwrap_or_default();
    if print || !display {
        outln!("{line}");
        if !print {
            outln!("no display here (DISPLAY is not set): run the line above where there is one, or under a virtual one (`xvfb-run -a syncroad replay …`)");
        }
        return Ok(Status::Success);
    }
    let started = std::time::SystemTime::now();
    let out = Command::new(&gui)
        .args(&args)
        .env("SUMO_HOME", &home)
        .output()
        .map_err(|e| anyhow::anyhow!("cannot start {}: {e}", gui.display()))?;
    let said = String::from_utf8_lossy(&out.stderr);
    let said = said
        .lines()
        .filter(|l| !l.starts_with("Fontconfig"))
        .collect::<Vec<_>>()
        .join("; ");
    if let Some(p) = snapshot {
        // The picture is written when the replay reaches its time; sumo-gui 1.28 can crash
        // while quitting after it (seen under a virtual display), which leaves it whole.
        let fresh = std::fs::metadata(&p)
            .and_then(|m| m.modified())
            .is_ok_and(|t| t >= started);
        if !fresh {
            anyhow::bail!(
                "sumo-gui ({}) took no snapshot into {}: {said}",
                out.status,
                p.display()
            );
        }
        if !out.status.success() {
            crate::stdout::errln!(
                "note: sumo-gui {} while quitting, after it wrote the snapshot",
                exit_words(&out.status)
            );
        }
        outln!("wrote {} (the replay at t = {at_s} s)", p.display());
    } else if !out.status.success() {
        crate::stdout::errln!("note: sumo-gui {}: {said}", exit_words(&out.status));
    }
    Ok(Status::Success)
}

/// How a program ended, in words.
fn exit_words(status: &std::process::ExitStatus) -> String {
    use std::os::unix::process::ExitStatusExt;
    match (status.code(), status.signal()) {
        (Some(c), _) => format!("ended with exit code {c}"),
        (None, Some(s)) => format!("was ended by signal {s}"),
        _ => format!("ended ({status})"),
    }
}

/// SUMO closes its floating-car data when the run ends; a file without its closing tag was
/// cut short and cannot be replayed.
fn check_complete(fcd: &Path) -> anyhow::Result<()> {
    let mut f = std::fs::File::open(fcd)?;
    let len = f.metadata()?.len();
    f.seek(SeekFrom::Start(len.saturating_sub(64)))?;
    let mut tail = String::new();
    f.take(64).read_to_string(&mut tail).ok();
    if tail.trim_end().ends_with("</fcd-export>") {
        Ok(())
    } else {
        Err(InputError::new(format!(
            "{}: cut short (it does not end in </fcd-export>): SUMO did not finish writing it, so the run did not end normally; run it again with --fcd",
            fcd.display()
        ))
        .into())
    }
}

/// sumo-gui's view: white ground, vehicles coloured by speed from `vmin` (the speed map's
/// dark end) to `vmax` (its bright end), and a snapshot when asked for.
fn view_settings(vmin: f64, vmax: f64, snapshot: Option<&Path>, at_s: f64) -> String {
    // The time-space diagram's colour map, sampled at eleven speeds (sumo-gui interpolates).
    let stops = (0..=10)
        .map(|k| {
            let v = vmin + (vmax - vmin) * f64::from(k) / 10.0;
            let c = crate::plots::speed_colour(v, vmin, vmax);
            format!(
                "                <entry color=\"{},{},{}\" threshold=\"{v:.3}\"/>\n",
                c.0, c.1, c.2
            )
        })
        .collect::<String>();
    let snap = snapshot
        .map(|p| {
            format!(
                "    <snapshot file=\"{}\" time=\"{at_s}\"/>\n",
                quick_xml::escape::escape(p.display().to_string())
            )
        })
        .unwrap_or_default();
    format!(
        "<viewsettings>\n    <scheme name=\"syncroad: by speed\">\n        <background backgroundColor=\"white\" showGrid=\"0\"/>\n        <vehicles vehicleMode=\"{BY_SPEED}\" vehicleQuality=\"2\" vehicle_minSize=\"1\" vehicle_exaggeration=\"1\">\n            <colorScheme name=\"by speed\" interpolated=\"1\">\n{stops}            </colorScheme>\n        </vehicles>\n    </scheme>\n    <delay value=\"20\"/>\n{snap}</viewsettings>\n"
    )
}
