//! Watching finished runs: SUMO's floating-car data of a run, its replay (headless in SUMO and
//! in sumo-gui under a virtual display), and animations drawn from the trajectories.

mod common;
use common::*;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// SUMO's `sumo` program of the project's virtualenv.
fn sumo_bin() -> PathBuf {
    repo().join(".venv/lib/python3.11/site-packages/sumo/bin/sumo")
}

/// An FCD file: (time in ms, vehicle id) → (x, y, speed, lane).
fn fcd(path: &Path) -> BTreeMap<(i64, String), (f64, f64, f64, String)> {
    let text = std::fs::read_to_string(path).unwrap();
    let doc = roxmltree::Document::parse(&text).unwrap();
    let mut out = BTreeMap::new();
    for ts in doc
        .root_element()
        .children()
        .filter(|n| n.has_tag_name("timestep"))
    {
        let t: f64 = ts.attribute("time").unwrap().parse().unwrap();
        for v in ts.children().filter(|n| n.has_tag_name("vehicle")) {
            let num = |a: &str| v.attribute(a).unwrap().parse::<f64>().unwrap();
            out.insert(
                (
                    (t * 1000.0).round() as i64,
                    v.attribute("id").unwrap().to_string(),
                ),
                (
                    num("x"),
                    num("y"),
                    num("speed"),
                    v.attribute("lane").unwrap().to_string(),
                ),
            );
        }
    }
    out
}

/// `trajectories.csv`: (time in ms, vehicle) → (speed, position).
fn rows(dir: &Path) -> BTreeMap<(i64, usize), (f64, f64)> {
    let text = std::fs::read_to_string(dir.join("trajectories.csv")).unwrap();
    text.lines()
        .skip(1)
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            let t: f64 = f[0].parse().unwrap();
            (
                ((t * 1000.0).round() as i64, f[1].parse().unwrap()),
                (f[2].parse().unwrap(), f[3].parse().unwrap()),
            )
        })
        .collect()
}

/// A short Sugiyama run (`horizon_s`) into `dir/NAME`: `how` is `run` (SUMO) with its extra
/// flags, or `simulate` (the native simulator); the verdict may go either way.
fn sugiyama_run(dir: &Path, name: &str, horizon_s: f64, how: &[&str]) -> PathBuf {
    let sc = edited_scenario(dir, "sugiyama-ring", |s| {
        s["horizon_s"] = serde_json::json!(horizon_s);
    });
    let out = dir.join(name);
    let (code, stdout, stderr) = run(bin()
        .args(how)
        .args(["--no-plots", "-q", "--out"])
        .arg(&out)
        .arg(&sc));
    assert!(code == 0 || code == 1, "{how:?}: {stdout}\n{stderr}");
    out
}

/// A short Sugiyama run in SUMO with SUMO's floating-car data, into `dir/run`.
fn sumo_run_with_fcd(dir: &Path, horizon_s: f64) -> PathBuf {
    sugiyama_run(dir, "run", horizon_s, &["run", "--fcd"])
}

/// A point of a polyline `[s, x, y]` at `s` (linear between points, wrapped on `length`).
fn along(points: &[[f64; 3]], length: f64, s: f64) -> (f64, f64) {
    let s = s.rem_euclid(length);
    let k = points.partition_point(|p| p[0] <= s);
    let (a, b) = if k == 0 || k == points.len() {
        let last = points[points.len() - 1];
        let first = points[0];
        (last, [first[0] + length, first[1], first[2]])
    } else {
        (points[k - 1], points[k])
    };
    let s = if s < a[0] { s + length } else { s };
    let f = (s - a[0]) / (b[0] - a[0]);
    (a[1] + f * (b[1] - a[1]), a[2] + f * (b[2] - a[2]))
}

/// SUMO itself, from the run's replay configuration in `work` and with its own FCD output (into
/// `file`), puts every vehicle of the floating-car data `recorded` where it was recorded (to
/// FCD's 0.01 m), at the recorded times, up to the end of the replay (whose last step, the
/// horizon's, is not written).
fn replays_where_recorded(
    work: &Path,
    file: &Path,
    recorded: &BTreeMap<(i64, String), (f64, f64, f64, String)>,
) {
    let p = std::process::Command::new(sumo_bin())
        .arg("-c")
        .arg(work.join("replay.sumocfg"))
        .arg("--fcd-output")
        .arg(file)
        .output()
        .unwrap();
    assert!(p.status.success(), "{}", String::from_utf8_lossy(&p.stderr));
    let replayed = fcd(file);
    assert!(replayed.len() >= recorded.len() - 22, "{}", replayed.len());
    let mut worst: f64 = 0.0;
    for (k, (x, y, _, _)) in &replayed {
        let (rx, ry, _, _) = &recorded[k];
        worst = worst.max((x - rx).abs()).max((y - ry).abs());
    }
    assert!(worst <= 0.01 + 1e-9, "replayed positions off by {worst} m");
}

/// A run made with `--fcd` holds SUMO's own floating-car data of that very run (its speeds are
/// the trajectories' speeds to FCD's two decimals), SUMO replays it headlessly from the run's
/// replay configuration with every vehicle where it was recorded (to FCD's 0.01 m), and the
/// run's road trace puts a vehicle's front bumper where SUMO's own coordinates put it.
#[test]
fn a_run_with_fcd_replays_in_sumo_where_it_was_recorded() {
    let dir = tmpdir("replay-headless");
    let out = sumo_run_with_fcd(&dir, 40.0);
    let work = out.join("sumo");
    for f in [
        "fcd.xml",
        "replay.sumocfg",
        "replay.types.xml",
        "replay.net.xml",
        "road.json",
    ] {
        assert!(work.join(f).is_file(), "{f}");
    }
    let recorded = fcd(&work.join("fcd.xml"));
    let traj = rows(&out);
    assert_eq!(
        recorded.len(),
        traj.len(),
        "one FCD entry per recorded sample"
    );
    for ((t, i), (v, _)) in &traj {
        let (_, _, fv, _) = &recorded[&(*t, format!("v{i}"))];
        assert!(
            (fv - v).abs() <= 0.005 + 1e-9,
            "t = {t} ms, v{i}: {fv} vs {v}"
        );
    }
    replays_where_recorded(&work, &dir.join("replayed.xml"), &recorded);
    // The run folder travels: every path of its replay configuration is relative to it (the
    // network copied beside it), so a copy elsewhere replays the same.
    let cfg = std::fs::read_to_string(work.join("replay.sumocfg")).unwrap();
    let doc = roxmltree::Document::parse(&cfg).unwrap();
    for n in doc.descendants().filter(|n| n.attribute("value").is_some()) {
        let v = n.attribute("value").unwrap();
        assert!(
            !v.starts_with('/'),
            "{}: {v} is absolute",
            n.tag_name().name()
        );
    }
    let copy = dir.join("elsewhere/run");
    std::fs::create_dir_all(copy.join("sumo")).unwrap();
    for f in std::fs::read_dir(&work).unwrap() {
        let f = f.unwrap().path();
        if f.is_file() {
            std::fs::copy(&f, copy.join("sumo").join(f.file_name().unwrap())).unwrap();
        }
    }
    replays_where_recorded(
        &copy.join("sumo"),
        &dir.join("replayed-copy.xml"),
        &recorded,
    );
    // On another machine the network the run named is not there: the copy's road trace finds
    // the network beside it, and draws the same road.
    let moved = copy.join("sumo/road.json");
    let mut doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&moved).unwrap()).unwrap();
    doc["net"] = serde_json::json!("/nowhere/on/this/machine/ring.net.xml");
    std::fs::write(&moved, doc.to_string()).unwrap();
    let there = syncroad_sumo::RoadTrace::read(&moved).unwrap();
    assert_eq!(there.net, copy.join("sumo/replay.net.xml"));
    let here = syncroad_sumo::RoadTrace::read(&work.join("road.json")).unwrap();
    assert_eq!(there.geometry().unwrap(), here.geometry().unwrap());
    // The road trace: a vehicle's trajectory position (rear bumper) plus its length (5 m) is its
    // front bumper, which is where FCD puts a vehicle.
    let trace = syncroad_sumo::RoadTrace::read(&work.join("road.json")).unwrap();
    let geometry = trace.geometry().unwrap();
    let length = trace.length_m();
    let mut worst: f64 = 0.0;
    for ((t, i), (_, q)) in traj.iter().filter(|((t, _), _)| t % 5000 == 0) {
        let (x, y) = along(&geometry, length, q + 5.0);
        let (fx, fy, _, _) = &recorded[&(*t, format!("v{i}"))];
        worst = worst.max((x - fx).hypot(y - fy));
    }
    assert!(
        worst < 0.03,
        "road trace off SUMO's coordinates by {worst} m"
    );
    // `replay` prints the command where there is no display (and with --print).
    let (code, stdout, stderr) = run(bin()
        .arg("replay")
        .arg(&out)
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY"));
    assert_eq!(code, 0, "{stderr}");
    assert!(
        stdout.contains("sumo-gui -c") && stdout.contains("replay.sumocfg"),
        "{stdout}"
    );
    assert!(stdout.contains("no display here"), "{stdout}");
}

/// `--fcd-every 10` has SUMO write its floating-car data every tenth step: at the 41 whole
/// seconds of a 40-s run at Δt = 0.1 s, each vehicle's entry that of the same run's every-step
/// trajectory at that time, and the replay steps a second at a time, so that SUMO replays
/// every vehicle where and when it was recorded. The flag needs `--fcd` and a k ≥ 1, and the
/// native simulator, which has no floating-car data, refuses `--fcd`.
#[test]
fn fcd_every_k_steps_is_written_at_that_interval_and_replays_at_it() {
    let dir = tmpdir("fcd-every");
    let out = sugiyama_run(
        &dir,
        "run",
        40.0,
        &["run", "--fcd", "--fcd-every", "10", "--record-every", "1"],
    );
    let work = out.join("sumo");
    let recorded = fcd(&work.join("fcd.xml"));
    let times: std::collections::BTreeSet<i64> = recorded.keys().map(|(t, _)| *t).collect();
    assert_eq!(
        times.iter().copied().collect::<Vec<_>>(),
        (0..=40).map(|s| s * 1000).collect::<Vec<_>>(),
        "one FCD time step a second, from 0 to the horizon"
    );
    let traj = rows(&out);
    assert_eq!(
        recorded.len(),
        41 * 22,
        "22 vehicles at each of the 41 times"
    );
    for ((t, id), (_, _, v, _)) in &recorded {
        let i: usize = id.trim_start_matches('v').parse().unwrap();
        let (tv, _) = traj[&(*t, i)];
        assert!(
            (v - tv).abs() <= 0.005 + 1e-9,
            "t = {t} ms, {id}: {v} vs {tv}"
        );
    }
    let cfg = std::fs::read_to_string(work.join("replay.sumocfg")).unwrap();
    assert!(cfg.contains(r#"<step-length value="1"/>"#), "{cfg}");
    replays_where_recorded(&work, &dir.join("replayed.xml"), &recorded);

    let sc = repo().join("scenarios/sugiyama-ring.json");
    let (code, _, stderr) = run(bin()
        .args(["run", "--fcd", "--fcd-every", "0", "--out"])
        .arg(dir.join("zero"))
        .arg(&sc));
    assert_eq!(code, 2, "{stderr}");
    assert!(stderr.contains("--fcd-every = 0: must be ≥ 1"), "{stderr}");
    let (code, _, stderr) = run(bin()
        .args(["run", "--fcd-every", "10", "--out"])
        .arg(dir.join("alone"))
        .arg(&sc));
    assert_eq!(code, 2, "{stderr}");
    assert!(stderr.contains("--fcd"), "{stderr}");
    let (code, _, stderr) = run(bin()
        .args(["run", "--fcd", "--out"])
        .arg(dir.join("native"))
        .arg(repo().join("scenarios/ring-theorem1.json")));
    assert_eq!(code, 2, "{stderr}");
    assert!(
        stderr.contains("--fcd: a SUMO option") && stderr.contains("\"native\""),
        "{stderr}"
    );
    for d in ["zero", "alone", "native"] {
        assert!(!dir.join(d).exists(), "{d}: refused before writing");
    }
}

/// sumo-gui itself replays a run under a virtual display (Xvfb) and takes its own snapshot:
/// the picture shows the ring (dark road pixels on a circle round the picture's centre) with
/// coloured vehicles on it.
#[test]
fn sumo_gui_replays_a_run_into_a_snapshot_of_the_ring() {
    if std::process::Command::new("xvfb-run")
        .arg("--help")
        .output()
        .is_err()
    {
        eprintln!("skipped: xvfb-run is not installed (scripts/test.sh installs Debian's xvfb)");
        return;
    }
    let dir = tmpdir("replay-gui");
    let out = sumo_run_with_fcd(&dir, 20.0);
    let snap = dir.join("snap.png");
    let (code, stdout, stderr) = run(std::process::Command::new("xvfb-run")
        .args(["-a", "-s", "-screen 0 1280x1024x24"])
        .arg(env!("CARGO_BIN_EXE_syncroad"))
        .arg("replay")
        .arg(&out)
        .arg("--snapshot")
        .arg(&snap)
        .args(["--at-s", "10"]));
    assert_eq!(code, 0, "{stdout}\n{stderr}");
    assert!(stdout.contains("wrote"), "{stdout}");
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&snap).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).unwrap();
    let (w, h) = (info.width as usize, info.height as usize);
    let channels = info.line_size / w;
    let px = |x: usize, y: usize| {
        let o = y * info.line_size + x * channels;
        (buf[o], buf[o + 1], buf[o + 2])
    };
    let mut dark = Vec::new();
    let mut coloured = 0usize;
    for y in 0..h {
        for x in 0..w {
            let (r, g, b) = px(x, y);
            if r < 40 && g < 40 && b < 40 {
                dark.push((x as f64, y as f64));
            }
            let (hi, lo) = (r.max(g).max(b), r.min(g).min(b));
            if hi - lo > 60 {
                coloured += 1;
            }
        }
    }
    assert!(
        dark.len() > w * h / 100,
        "hardly any road: {} dark pixels",
        dark.len()
    );
    let n = dark.len() as f64;
    let (cx, cy) = dark
        .iter()
        .fold((0.0, 0.0), |a, p| (a.0 + p.0 / n, a.1 + p.1 / n));
    let mut radii: Vec<f64> = dark.iter().map(|p| (p.0 - cx).hypot(p.1 - cy)).collect();
    radii.sort_by(f64::total_cmp);
    let (r10, r50, r90) = (
        radii[radii.len() / 10],
        radii[radii.len() / 2],
        radii[9 * radii.len() / 10],
    );
    // A ring: the road's pixels lie in a band round the centre, not filled and not scattered.
    assert!(r50 > 0.15 * w.min(h) as f64, "ring radius {r50} px");
    assert!(
        r10 > 0.8 * r50 && r90 < 1.2 * r50,
        "not a ring: radii {r10} {r50} {r90}"
    );
    assert!(
        (cx - w as f64 / 2.0).abs() < 0.1 * w as f64,
        "centre {cx} of {w}"
    );
    // Vehicles coloured by speed (22 cars of some hundred pixels each).
    assert!(coloured > 500, "{coloured} coloured pixels");
}

/// Reconstructs every frame of a GIF (frames are boxes drawn over the previous picture, with
/// one index meaning "unchanged").
fn gif_frames(path: &Path) -> (usize, usize, Vec<Vec<u8>>, Vec<u16>) {
    let mut opts = gif::DecodeOptions::new();
    opts.set_color_output(gif::ColorOutput::Indexed);
    let mut d = opts.read_info(std::fs::File::open(path).unwrap()).unwrap();
    let (w, h) = (usize::from(d.width()), usize::from(d.height()));
    let mut canvas = vec![0u8; w * h];
    let (mut frames, mut delays) = (Vec::new(), Vec::new());
    while let Some(f) = d.read_next_frame().unwrap() {
        let (l, t, fw) = (
            usize::from(f.left),
            usize::from(f.top),
            usize::from(f.width),
        );
        for (k, &p) in f.buffer.iter().enumerate() {
            if Some(p) != f.transparent {
                canvas[(t + k / fw) * w + l + k % fw] = p;
            }
        }
        frames.push(canvas.clone());
        delays.push(f.delay);
    }
    (w, h, frames, delays)
}

/// A native ring's animation: one frame per 0.3 simulated seconds at 10 frames per second and
/// a speed-up of 3, and in the last frame every vehicle sits where the circle of the ring's
/// length puts it (angle = position / radius, computed here), in a speed colour ordered as its
/// speed, with bare road between vehicles.
#[test]
fn animate_draws_each_vehicle_at_its_place_on_the_ring_in_its_speed_colour() {
    let dir = tmpdir("animate-native");
    let out = sugiyama_run(&dir, "run", 30.0, &["simulate"]);
    let (code, stdout, stderr) = run(bin().arg("animate").arg(&out).args([
        "--fps",
        "10",
        "--speedup",
        "3",
        "--size",
        "300",
    ]));
    assert_eq!(code, 0, "{stderr}");
    assert!(stdout.contains("101 frames"), "{stdout}");
    let (w, h, frames, delays) = gif_frames(&out.join("animation.gif"));
    assert_eq!((w, h), (300 + 112, 26 + 22 + 300));
    assert_eq!(frames.len(), 101);
    assert!(delays.iter().all(|d| *d == 10));
    // The last frame is t = 30 s, a recorded sample.
    let traj = rows(&out);
    let last: Vec<(f64, f64)> = (0..22).map(|i| traj[&(30_000, i)]).collect();
    let frame = frames.last().unwrap();
    let radius_m = 230.0 / std::f64::consts::TAU;
    // The panel: 300 px square below the clock (26 px) and the title (22 px), 14 px margin,
    // the circle's diameter filling the 272 px between.
    let (cx, cy, rpx) = (14.0 + 136.0, 48.0 + 14.0 + 136.0, 136.0);
    let at = |s: f64| {
        let a = s / radius_m;
        let (x, y) = (cx + rpx * a.cos(), cy - rpx * a.sin());
        frame[y.round() as usize * w + x.round() as usize]
    };
    let white = frame[5 * w + w - 5];
    let colours: Vec<u8> = last.iter().map(|(_, q)| at(*q)).collect();
    for (i, c) in colours.iter().enumerate() {
        assert_ne!(
            *c, white,
            "vehicle {i} is not drawn where the circle puts it"
        );
    }
    // Palette indices of the speed scale grow with the speed: faster is never darker.
    let mut by_speed: Vec<(f64, u8)> = last
        .iter()
        .map(|(v, _)| *v)
        .zip(colours.iter().copied())
        .collect();
    by_speed.sort_by(|a, b| a.0.total_cmp(&b.0));
    assert!(
        by_speed.windows(2).all(|p| p[0].1 <= p[1].1),
        "{by_speed:?}"
    );
    // Midway along the gap behind vehicle 0 (its follower's front bumper is 5 m ahead of its
    // own rear) the road shows: the road's grey, neither white nor a vehicle's colour.
    let gap_mid = 0.5 * (last[0].1 + last[1].1 + 5.0);
    let g = at(gap_mid);
    assert_ne!(g, white);
    assert!(!colours.contains(&g), "vehicle colour in the gap: {g}");
}

/// What is not a run is refused with exit 2, naming the file and what would be valid, and
/// nothing is written outside the run's folder.
#[test]
fn animate_and_replay_refuse_what_is_not_a_run_and_write_nothing_outside_it() {
    let dir = tmpdir("watch-refusals");
    let empty = dir.join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    let (code, _, stderr) = run(bin().arg("animate").arg(&empty));
    assert_eq!(code, 2, "{stderr}");
    assert!(
        stderr.contains("not a run folder") && stderr.contains("metrics.json"),
        "{stderr}"
    );
    let (code, _, stderr) = run(bin().arg("replay").arg(&empty));
    assert_eq!(code, 2, "{stderr}");
    assert!(stderr.contains("not a run folder"), "{stderr}");
    // A native run: replay says it needs a SUMO run and how to make one.
    let native = sugiyama_run(&dir, "native", 12.0, &["simulate"]);
    let (code, _, stderr) = run(bin().arg("replay").arg(&native));
    assert_eq!(code, 2, "{stderr}");
    assert!(
        stderr.contains("a native run") && stderr.contains("--fcd"),
        "{stderr}"
    );
    // Bad options name the option.
    let (code, _, stderr) = run(bin().arg("animate").arg(&native).args(["--fps", "0"]));
    assert_eq!(code, 2, "{stderr}");
    assert!(stderr.contains("--fps = 0"), "{stderr}");
    // Two runs need a name for their one GIF.
    let (code, _, stderr) = run(bin().arg("animate").arg(&native).arg(&native));
    assert_eq!(code, 2, "{stderr}");
    assert!(stderr.contains("--out"), "{stderr}");
    // Trajectories cut short in the middle of a sample: refused, naming the file and line.
    let text = std::fs::read_to_string(native.join("trajectories.csv")).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    std::fs::write(
        native.join("trajectories.csv"),
        lines[..lines.len() - 3].join("\n") + "\n",
    )
    .unwrap();
    let before: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .flatten()
        .map(|e| e.file_name())
        .collect();
    let (code, _, stderr) = run(bin().arg("animate").arg(&native));
    assert_eq!(code, 2, "{stderr}");
    assert!(
        stderr.contains("trajectories.csv line") && stderr.contains("cut short"),
        "{stderr}"
    );
    assert!(!native.join("animation.gif").exists());
    let after: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .flatten()
        .map(|e| e.file_name())
        .collect();
    assert_eq!(before, after);
    // A SUMO run made without --fcd: replay says how to make one with it.
    let plain = sugiyama_run(&dir, "plain", 12.0, &["run"]);
    let (code, _, stderr) = run(bin().arg("replay").arg(&plain));
    assert_eq!(code, 2, "{stderr}");
    assert!(
        stderr.contains("without --fcd") && stderr.contains("fcd.xml"),
        "{stderr}"
    );
    // ... and it animates (the network's geometry).
    let (code, stdout, stderr) = run(bin().arg("animate").arg(&plain).args(["--speedup", "1"]));
    assert_eq!(code, 0, "{stderr}");
    assert!(stdout.contains("121 frames"), "{stdout}");
}

/// A sweep's kept SUMO runs write their floating-car data with `--fcd`, each point its own,
/// and replay from their folders; `--fcd` without `--keep-runs` is refused (no run folder
/// would hold it).
#[test]
fn a_sweep_keeps_each_points_floating_car_data_for_replay() {
    let dir = tmpdir("sweep-fcd");
    let sc = edited_scenario(&dir, "sugiyama-ring", |s| {
        s["horizon_s"] = serde_json::json!(12.0);
    });
    let spec = dir.join("spec.json");
    std::fs::write(
        &spec,
        format!(
            r#"{{"name": "fcd", "base": "{}", "backend": "sumo", "runs": ["protocol"], "seeds": [1, 2]}}"#,
            sc.display()
        ),
    )
    .unwrap();
    let out = dir.join("out");
    let (code, _, stderr) = run(bin()
        .arg("sweep")
        .arg(&spec)
        .arg("--out")
        .arg(&out)
        .arg("--fcd"));
    assert_eq!(code, 2, "{stderr}");
    assert!(stderr.contains("--keep-runs"), "{stderr}");
    let (code, stdout, stderr) = run(bin().arg("sweep").arg(&spec).arg("--out").arg(&out).args([
        "--keep-runs",
        "--fcd",
        "--no-plots",
    ]));
    assert_eq!(code, 0, "{stdout}\n{stderr}");
    let (a, b) = (out.join("runs/0000000"), out.join("runs/0000001"));
    let (fa, fb) = (fcd(&a.join("sumo/fcd.xml")), fcd(&b.join("sumo/fcd.xml")));
    assert_eq!(fa.len(), 121 * 22);
    assert_eq!(fb.len(), 121 * 22);
    assert_ne!(fa, fb, "two seeds, two runs");
    let (code, stdout, stderr) = run(bin().arg("replay").arg(&b).arg("--print"));
    assert_eq!(code, 0, "{stderr}");
    assert!(
        stdout.contains("runs/0000001/sumo/replay.sumocfg"),
        "{stdout}"
    );
}

/// Black pixels in a frame's road area (below the clock and the title, left of the colour
/// bar), where only the ring of a controlled vehicle is black.
fn black_on_road(w: usize, frame: &[u8], size: usize) -> usize {
    (48..48 + size)
        .flat_map(|y| (0..size).map(move |x| y * w + x))
        .filter(|&k| frame[k] == 1)
        .count()
}

/// The vehicle a controller drives among humans is ringed in black, and only then: a mixed
/// ring of one law vehicle among 21 humans shows one ring's worth of black on the road (the
/// annulus around its disc), a ring of law vehicles none.
#[test]
fn animate_rings_the_controlled_vehicle_among_humans() {
    let dir = tmpdir("animate-marked");
    let sc = edited_scenario(&dir, "sugiyama-human", |s| {
        s["horizon_s"] = serde_json::json!(20.0);
    });
    let out = dir.join("cmp");
    let (code, stdout, stderr) = run(bin()
        .arg("compare")
        .arg(&sc)
        .args([
            "--baselines",
            "protocol",
            "--mixed",
            "1",
            "--no-plots",
            "--out",
        ])
        .arg(&out));
    assert!(code == 0 || code == 1, "{stdout}{stderr}");
    let m: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(out.join("protocol-mixed-1/metrics.json")).unwrap(),
    )
    .unwrap();
    let drivers: Vec<&str> = m["drivers"]
        .as_array()
        .unwrap()
        .iter()
        .map(|d| d.as_str().unwrap())
        .collect();
    assert_eq!(
        drivers.iter().filter(|d| **d == "protocol").count(),
        1,
        "{drivers:?}"
    );
    let mut black = Vec::new();
    for run_dir in ["protocol-mixed-1", "protocol"] {
        let gif = dir.join(format!("{run_dir}.gif"));
        let (code, _, stderr) = run(bin()
            .arg("animate")
            .arg(out.join(run_dir))
            .args(["--speedup", "20", "--size", "300", "--out"])
            .arg(&gif));
        assert_eq!(code, 0, "{stderr}");
        let (w, _, frames, _) = gif_frames(&gif);
        black.push(black_on_road(w, frames.last().unwrap(), 300));
    }
    eprintln!(
        "black pixels on the road: mixed {}, all-law {}",
        black[0], black[1]
    );
    // The ring is the annulus between radii r and r + 2 px, r = 2.2 m at the panel's scale
    // (272 px across the ring's 2·230.36/2π m): π((r + 2)² − r²) pixels, to rasterisation.
    let scale = 272.0 / (230.3592 / std::f64::consts::PI);
    let r: f64 = 2.2 * scale;
    let annulus = std::f64::consts::PI * ((r + 2.0).powi(2) - r.powi(2));
    assert!(
        (black[0] as f64 - annulus).abs() < 0.25 * annulus,
        "mixed ring: {} black pixels, the ring's annulus {annulus:.0}",
        black[0]
    );
    assert_eq!(black[1], 0, "all-law ring: {} black pixels", black[1]);
}

/// With other traffic and `--fcd` a run draws every vehicle on the road (`time_space_all`),
/// placed from SUMO's floating-car data: the drawing holds exactly the records of vehicles on
/// the road's edges (the slow car of the guide's track among the law's sixteen), counted here
/// from the same file independently.
#[test]
fn every_vehicle_on_the_road_is_drawn_from_the_floating_car_data() {
    let dir = tmpdir("field");
    let track = guide_track(&dir, &["slow.rou.xml"]);
    let text = std::fs::read_to_string(repo().join("examples/track/own-loop.json")).unwrap();
    let mut sc: serde_json::Value = serde_json::from_str(&text).unwrap();
    sc["horizon_s"] = 30.into();
    sc["sumo"]["routes"] = serde_json::json!(["slow.rou.xml"]);
    let path = track.join("field.json");
    std::fs::write(&path, sc.to_string()).unwrap();
    let out = dir.join("out");
    let (code, stdout, stderr) = run(bin()
        .args(["run", "--fcd", "-q"])
        .arg(&path)
        .arg("--out")
        .arg(&out));
    assert!(code == 0 || code == 1, "{stdout}\n{stderr}");
    let (code, stdout, _) = run(bin()
        .args(["run", "--fcd"])
        .arg(&path)
        .arg("--out")
        .arg(dir.join("again")));
    assert!(code == 0 || code == 1);
    assert!(
        stdout.contains("time_space_all (every vehicle on the road)"),
        "{stdout}"
    );
    assert!(out.join("time_space_all.png").is_file());
    let svg = std::fs::read_to_string(out.join("time_space_all.svg")).unwrap();
    let drawn = svg.matches("<circle").count();
    // The records on the road's edges, from the FCD and road.json.
    let road: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("sumo/road.json")).unwrap())
            .unwrap();
    let lanes: Vec<String> = road["lanes"]
        .as_array()
        .unwrap()
        .iter()
        .map(|l| l["id"].as_str().unwrap().to_string())
        .collect();
    let edge = |lane: &str| lane.rsplit_once('_').map_or(lane, |(e, _)| e).to_string();
    let edges: Vec<String> = lanes
        .iter()
        .filter(|l| !l.starts_with(':'))
        .map(|l| edge(l))
        .collect();
    let records = fcd(&out.join("sumo/fcd.xml"));
    let on_road = records
        .values()
        .filter(|r| lanes.contains(&r.3) || (!r.3.starts_with(':') && edges.contains(&edge(&r.3))))
        .count();
    let slow = records.keys().filter(|k| k.1 == "slow").count();
    eprintln!(
        "field: {drawn} points drawn, {on_road} FCD records on the road, {slow} of the slow car"
    );
    assert!(slow > 200, "the slow car is on the road");
    assert_eq!(drawn, on_road);
}
