//! Roads through networks made by a real tool: netconvert (from the project's virtualenv)
//! builds every network here from plain node/edge files or an OpenStreetMap file the test
//! writes. Lengths are checked against sumolib (SUMO's own Python network reader), runs against
//! the native simulator, and SUMO runs are real.

use std::path::{Path, PathBuf};
use std::process::Command;

use approx::assert_relative_eq;
use syncroad_control::native::{simulate, NativeOptions};
use syncroad_control::scenario::ScenarioFile;
use syncroad_control::sumo_facts::AllVehicles;
use syncroad_control::Scenario;
use syncroad_sumo::{load_road, run_scenario, NetReader, RunOptions, SumoRun, WorkerCommand};

fn venv() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../.venv")
}

fn work(name: &str) -> PathBuf {
    let d = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("networks")
        .join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn opts(dir: &Path) -> RunOptions {
    RunOptions::new(
        dir.join("run"),
        WorkerCommand::binary(env!("CARGO_BIN_EXE_syncroad-sumo-worker")),
    )
}

/// Runs the venv's netconvert with `args` in `dir`, writing `out.net.xml`.
fn netconvert(dir: &Path, args: &[&str]) -> PathBuf {
    let bin = venv().join("lib/python3.11/site-packages/sumo/bin/netconvert");
    let out = dir.join("out.net.xml");
    let st = Command::new(&bin)
        .current_dir(dir)
        .args(args)
        .args(["--no-turnarounds", "true", "--no-warnings", "true", "-o"])
        .arg(&out)
        .output()
        .expect("netconvert runs");
    assert!(
        st.status.success(),
        "netconvert failed: {}",
        String::from_utf8_lossy(&st.stderr)
    );
    out
}

/// A two-lane loop of 8 edges around an octagon (100 m radius, 20 m/s) with a one-lane branch
/// `out` leaving it at node n1 (a junction with one road in and two out).
fn two_lane_loop(dir: &Path) -> PathBuf {
    let mut nod = String::from("<nodes>\n");
    for i in 0..8 {
        let a = 2.0 * std::f64::consts::PI * i as f64 / 8.0;
        nod += &format!(
            "  <node id=\"n{i}\" x=\"{:.3}\" y=\"{:.3}\"/>\n",
            100.0 * a.cos(),
            100.0 * a.sin()
        );
    }
    nod += "  <node id=\"x\" x=\"250\" y=\"60\"/>\n</nodes>\n";
    let mut edg = String::from("<edges>\n");
    for i in 0..8 {
        edg += &format!(
            "  <edge id=\"e{i}\" from=\"n{i}\" to=\"n{}\" numLanes=\"2\" speed=\"20\"/>\n",
            (i + 1) % 8
        );
    }
    edg += "  <edge id=\"out\" from=\"n1\" to=\"x\" numLanes=\"1\" speed=\"20\"/>\n</edges>\n";
    std::fs::write(dir.join("loop.nod.xml"), nod).unwrap();
    std::fs::write(dir.join("loop.edg.xml"), edg).unwrap();
    netconvert(
        dir,
        &[
            "--node-files",
            "loop.nod.xml",
            "--edge-files",
            "loop.edg.xml",
        ],
    )
}

/// A three-lane highway of four 500 m edges h0..h3 (30 m/s); with `bus_lane`, lane 0 of h2
/// admits buses only; with `merge`, lane 2 of h2 continues onto lane 1 of h3.
fn highway(dir: &Path, bus_lane: bool, merge: bool) -> PathBuf {
    let nod = "<nodes>\n".to_string()
        + &(0..5)
            .map(|i| format!("  <node id=\"k{i}\" x=\"{}\" y=\"0\"/>\n", 500 * i))
            .collect::<String>()
        + "</nodes>\n";
    let mut edg = String::from("<edges>\n");
    for i in 0..4 {
        let lane = if bus_lane && i == 2 {
            "<lane index=\"0\" allow=\"bus\"/>"
        } else {
            ""
        };
        edg += &format!(
            "  <edge id=\"h{i}\" from=\"k{i}\" to=\"k{}\" numLanes=\"3\" speed=\"30\">{lane}</edge>\n",
            i + 1
        );
    }
    edg += "</edges>\n";
    std::fs::write(dir.join("hw.nod.xml"), nod).unwrap();
    std::fs::write(dir.join("hw.edg.xml"), edg).unwrap();
    let mut args = vec!["--node-files", "hw.nod.xml", "--edge-files", "hw.edg.xml"];
    if merge {
        std::fs::write(
            dir.join("hw.con.xml"),
            "<connections>\n  <connection from=\"h2\" to=\"h3\" fromLane=\"0\" toLane=\"0\"/>\n  <connection from=\"h2\" to=\"h3\" fromLane=\"1\" toLane=\"1\"/>\n  <connection from=\"h2\" to=\"h3\" fromLane=\"2\" toLane=\"1\"/>\n</connections>\n",
        )
        .unwrap();
        args.extend(["--connection-files", "hw.con.xml"]);
    }
    netconvert(dir, &args)
}

/// The driven length along `edges` on lane `lane` (closed back to the first edge when
/// `closed`), computed by sumolib from the same file: normal lanes plus the via lanes of the
/// lane-to-lane connections.
fn sumolib_length(net: &Path, edges: &[&str], lane: usize, closed: bool) -> f64 {
    sumolib_length_on(net, edges, &vec![lane; edges.len()], closed)
}

/// [`sumolib_length`] on lane `lanes[i]` of edge `i`.
fn sumolib_length_on(net: &Path, edges: &[&str], lanes: &[usize], closed: bool) -> f64 {
    let script = r#"
import sys, sumolib
net = sumolib.net.readNet(sys.argv[1], withInternal=True)
closed = sys.argv[2] == "1"; pairs_in = sys.argv[3:]
edges = pairs_in[0::2]; lanes = [int(x) for x in pairs_in[1::2]]
total = 0.0
pairs = len(edges) if closed else len(edges) - 1
for e, l in zip(edges, lanes):
    total += net.getEdge(e).getLane(l).getLength()
for i in range(pairs):
    j = (i + 1) % len(edges)
    a, b = net.getEdge(edges[i]), net.getEdge(edges[j])
    c = [c for c in a.getConnections(b) if c.getFromLane().getIndex() == lanes[i] and c.getToLane().getIndex() == lanes[j]][0]
    via = c.getViaLaneID()
    while via:
        total += net.getLane(via).getLength()
        nxt = [x for x in net.getLane(via).getOutgoing() if x.getToLane().getEdge().getID() == b.getID()]
        via = nxt[0].getViaLaneID() if nxt else ""
print(repr(total))
"#;
    let out = Command::new(venv().join("bin/python"))
        .arg("-c")
        .arg(script)
        .arg(net)
        .arg(if closed { "1" } else { "0" })
        .args(
            edges
                .iter()
                .zip(lanes)
                .flat_map(|(e, l)| [e.to_string(), l.to_string()]),
        )
        .output()
        .expect("python runs");
    assert!(
        out.status.success(),
        "sumolib: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout)
        .unwrap()
        .trim()
        .parse()
        .unwrap()
}

/// A highway with an on-ramp: `h0` (two lanes, 400 m) and the one-lane `ramp` join at k1,
/// where `h1` (three lanes, 400 m) starts: the ramp onto lane 0 (the acceleration lane), the
/// highway's lanes 0 and 1 onto lanes 1 and 2; `h2` (three lanes, 400 m) continues them. 30 m/s.
fn on_ramp(dir: &Path) -> PathBuf {
    std::fs::write(
        dir.join("ramp.nod.xml"),
        "<nodes>\n  <node id=\"k0\" x=\"0\" y=\"0\"/>\n  <node id=\"r0\" x=\"0\" y=\"-80\"/>\n  <node id=\"k1\" x=\"400\" y=\"0\"/>\n  <node id=\"k2\" x=\"800\" y=\"0\"/>\n  <node id=\"k3\" x=\"1200\" y=\"0\"/>\n</nodes>\n",
    )
    .unwrap();
    std::fs::write(
        dir.join("ramp.edg.xml"),
        "<edges>\n  <edge id=\"h0\" from=\"k0\" to=\"k1\" numLanes=\"2\" speed=\"30\"/>\n  <edge id=\"ramp\" from=\"r0\" to=\"k1\" numLanes=\"1\" speed=\"30\"/>\n  <edge id=\"h1\" from=\"k1\" to=\"k2\" numLanes=\"3\" speed=\"30\"/>\n  <edge id=\"h2\" from=\"k2\" to=\"k3\" numLanes=\"3\" speed=\"30\"/>\n</edges>\n",
    )
    .unwrap();
    std::fs::write(
        dir.join("ramp.con.xml"),
        "<connections>\n  <connection from=\"ramp\" to=\"h1\" fromLane=\"0\" toLane=\"0\"/>\n  <connection from=\"h0\" to=\"h1\" fromLane=\"0\" toLane=\"1\"/>\n  <connection from=\"h0\" to=\"h1\" fromLane=\"1\" toLane=\"2\"/>\n  <connection from=\"h1\" to=\"h2\" fromLane=\"0\" toLane=\"0\"/>\n  <connection from=\"h1\" to=\"h2\" fromLane=\"1\" toLane=\"1\"/>\n  <connection from=\"h1\" to=\"h2\" fromLane=\"2\" toLane=\"2\"/>\n</connections>\n",
    )
    .unwrap();
    netconvert(
        dir,
        &[
            "--node-files",
            "ramp.nod.xml",
            "--edge-files",
            "ramp.edg.xml",
            "--connection-files",
            "ramp.con.xml",
        ],
    )
}

/// Every vehicle of a SUMO run with other traffic, from SUMO's summary (the record's
/// `all_vehicles`).
fn all_vehicles(run: &SumoRun, sc: &Scenario) -> AllVehicles {
    run.output(sc)
        .sumo
        .unwrap()
        .all_vehicles
        .expect("other traffic")
}

/// Validates scenario JSON with the network reader (relative paths from `dir`).
fn scenario(dir: &Path, json: &str) -> Result<Scenario, String> {
    ScenarioFile::from_json(json, "<test>")
        .map_err(|e| e.to_string())?
        .validate_with(dir, Some(&NetReader))
        .map_err(|e| e.to_string())
}

fn loop_json(road: &str, vehicles: usize, horizon_s: f64, gap: &str) -> String {
    format!(
        r#"{{"name": "user-loop", "seed": 7, "step_s": 0.1, "horizon_s": {horizon_s},
            "vehicles": {vehicles}, "road": {road},
            "model": {{"type": "delayed_driver",
                       "graph": {{"type": "bidirectional_ring", "gain_pred": 0.6, "gain_follow": 0.1}},
                       "delay_s": 0.5}},
            "initial": {{"speed_mps": 8.0, "perturbation": {{"speed_mps": 1.5}} {gap}}},
            "sumo": {{"net": "out.net.xml"}}}}"#
    )
}

/// The user's own slow car (`slow.rou.xml` in `dir`): 4 m/s, departing on lane 1 of the
/// two-lane loop, five laps (the file of `examples/track/slow.rou.xml`).
/// The last state of an FCD file where `leader` drives on the road's lanes (`road.json`, in
/// driving order, a closed road): its time, the id of the vehicle directly behind it along the
/// road, and the bumper gap between them (`leader`'s rear at `length_m` behind its front).
fn gap_behind(run: &Path, leader: &str, length_m: f64) -> Option<(f64, String, f64)> {
    let road: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("road.json")).unwrap()).unwrap();
    let mut start = std::collections::HashMap::new();
    let mut total = 0.0;
    for lane in road["lanes"].as_array().unwrap() {
        start.insert(lane["id"].as_str().unwrap().to_string(), total);
        total += lane["length_m"].as_f64().unwrap();
    }
    let text = std::fs::read_to_string(run.join("fcd.xml")).unwrap();
    let attr = |line: &str, key: &str| -> Option<String> {
        let from = line.find(&format!(" {key}=\""))? + key.len() + 3;
        let to = line[from..].find('"')? + from;
        Some(line[from..to].to_string())
    };
    let mut found = None;
    for step in text.split("<timestep").skip(1) {
        let time: f64 = attr(step, "time")?.parse().ok()?;
        // Each vehicle on the road's lanes at its front bumper's distance along the road.
        let along: Vec<(String, f64)> = step
            .lines()
            .filter(|l| l.trim_start().starts_with("<vehicle"))
            .filter_map(|l| {
                let at = start.get(&attr(l, "lane")?)?;
                Some((attr(l, "id")?, at + attr(l, "pos")?.parse::<f64>().ok()?))
            })
            .collect();
        let Some(&(_, front)) = along.iter().find(|c| c.0 == leader) else {
            continue;
        };
        let behind = along
            .iter()
            .filter(|c| c.0 != leader)
            .map(|c| (c, (front - c.1).rem_euclid(total)))
            .min_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((c, d)) = behind {
            found = Some((time, c.0.clone(), d - length_m));
        }
    }
    found
}

fn slow_car(dir: &Path) {
    std::fs::write(
        dir.join("slow.rou.xml"),
        r#"<routes>
    <vType id="slow" maxSpeed="4" sigma="0"/>
    <route id="u_slow" edges="e4 e5 e6 e7 e0 e1 e2 e3" repeat="5"/>
    <vehicle id="slow" type="slow" route="u_slow" depart="0" departLane="1" departPos="20" departSpeed="4"/>
</routes>
"#,
    )
    .unwrap();
}

fn worst_speed_difference(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

mod loops {
    use super::*;

    const CYCLE: [&str; 8] = ["e0", "e1", "e2", "e3", "e4", "e5", "e6", "e7"];

    #[test]
    fn the_loop_is_measured_as_sumolib_measures_it_on_either_lane() {
        let dir = work("measure");
        let net = two_lane_loop(&dir);
        for lane in [0, 1] {
            let road = format!(
                r#"{{"type": "loop", "edges": {:?}, "lane": {lane}}}"#,
                CYCLE
            );
            let sc = scenario(&dir, &loop_json(&road, 10, 10.0, "")).unwrap();
            let reference = sumolib_length(&net, &CYCLE, lane, true);
            assert_relative_eq!(sc.ring_length_m().unwrap(), reference, epsilon = 1e-9);
            let r = load_road(&sc).unwrap();
            assert_eq!(r.lanes(), vec![lane; CYCLE.len()]);
            assert_eq!(r.normal_edges(), CYCLE.to_vec());
            // Eight junctions, one internal lane each on this net.
            assert_eq!(r.segments.len(), 16);
        }
        // The outer lane (0, the loop turns left) is the longer one.
        let l0 = sumolib_length(&net, &CYCLE, 0, true);
        let l1 = sumolib_length(&net, &CYCLE, 1, true);
        assert!(l0 > l1 + 10.0, "{l0} vs {l1}");
    }

    #[test]
    fn through_finds_the_cycle_starting_at_its_edge() {
        let dir = work("through");
        let net = two_lane_loop(&dir);
        let road = r#"{"type": "loop", "through": "e3", "lane": 1}"#;
        let sc = scenario(&dir, &loop_json(road, 10, 10.0, "")).unwrap();
        let m = sc.measured_road().unwrap();
        assert_eq!(
            m.edges,
            ["e3", "e4", "e5", "e6", "e7", "e0", "e1", "e2"].map(String::from)
        );
        assert_relative_eq!(
            m.length_m,
            sumolib_length(&net, &CYCLE, 1, true),
            epsilon = 1e-9
        );
    }

    /// On lane 1 of the two-lane loop (no other traffic, no lane changes) SUMO's ballistic
    /// update is the native simulator's rule: the delayed-driver law gives the same speeds
    /// to 1e-9 m/s, the native simulator using the loop's measured length; the vehicles keep
    /// circling for several laps past the junction with the branch, on their lane.
    #[test]
    fn the_law_on_a_user_loop_reproduces_the_native_simulator() {
        let dir = work("native");
        two_lane_loop(&dir);
        let road = format!(r#"{{"type": "loop", "edges": {:?}, "lane": 1}}"#, CYCLE);
        let sc = scenario(&dir, &loop_json(&road, 16, 200.0, "")).unwrap();
        let run = run_scenario(&sc, &opts(&dir)).unwrap();
        let fin = run.outcome().expect("horizon reached");
        let start = run.worker.start.as_ref().unwrap();
        assert_relative_eq!(
            start.road_length_m,
            sc.ring_length_m().unwrap(),
            epsilon = 1e-9
        );
        assert_eq!(start.vehicles, 16);
        assert_eq!(fin.totals.collision_steps, 0);
        assert_eq!(fin.totals.teleports, 0);
        assert_eq!(fin.totals.overrides, 0);
        let routes = std::fs::read_to_string(&run.request.routes_file).unwrap();
        assert!(routes.contains(r#"departLane="1""#), "{routes}");
        let native = simulate(&sc, NativeOptions::default()).trajectory;
        let sumo = run.trajectory(&sc);
        let worst = worst_speed_difference(&native.speeds_mps, &sumo.speeds_mps);
        eprintln!("user loop: largest SUMO-native speed difference {worst:.2e} m/s");
        assert!(worst < 1e-9, "largest speed difference {worst} m/s");
        let n = 16;
        let k = sumo.len() - 1;
        for i in 0..n {
            let travelled = sumo.positions_m[k * n + i] - sumo.positions_m[i];
            assert!(
                travelled > 2.0 * start.road_length_m,
                "vehicle {i}: {travelled} m"
            );
        }
        // Gaps close the loop at the end: lengths plus gaps are its measured length.
        let sum: f64 = sumo.gaps(k).iter().sum::<f64>() + 5.0 * n as f64;
        assert_relative_eq!(sum, start.road_length_m, epsilon = 1e-6);
        // The vehicles start at the scenario's spacing (gap_scale 1: its gaps already fill the
        // measured loop), so the gaps agree with the native simulator's at every sample.
        assert_relative_eq!(run.request.layout.gap_scale, 1.0, epsilon = 1e-12);
        for k in [0, k / 2, k] {
            for (a, b) in native.gaps(k).iter().zip(sumo.gaps(k)) {
                assert_relative_eq!(*a, b, epsilon = 1e-6);
            }
        }
    }

    /// SUMO's own drivers on the two-lane loop, every other vehicle, behind law-driven ones
    /// at 8 m/s: left to SUMO's lane-change model they would overtake on lane 0 (and the gaps
    /// along lane 1 would turn negative); they keep lane 1 like the law's vehicles, so the
    /// order along the loop holds and every gap stays positive.
    #[test]
    fn sumo_drivers_keep_the_lane_on_a_two_lane_loop() {
        let dir = work("keep-lane");
        two_lane_loop(&dir);
        let road = format!(r#"{{"type": "loop", "edges": {:?}, "lane": 1}}"#, CYCLE);
        let sc = scenario(&dir, &loop_json(&road, 8, 120.0, "")).unwrap();
        let mut o = opts(&dir);
        o.drivers = (0..8)
            .map(|i| {
                (i % 2 == 1).then(|| syncroad_control::SumoDriver::parse("d", "krauss").unwrap())
            })
            .collect();
        let run = run_scenario(&sc, &o).unwrap();
        let fin = run.outcome().expect("horizon reached");
        assert_eq!(fin.totals.collision_steps, 0);
        let t = run.trajectory(&sc);
        let mut min_gap = f64::INFINITY;
        for k in 0..t.len() {
            min_gap = t.gaps(k).iter().copied().fold(min_gap, f64::min);
        }
        assert!(min_gap > 0.0, "smallest gap along lane 1: {min_gap} m");
    }

    /// The user's own traffic (`sumo.routes`) on lane 0 of the two-lane loop: a slow car and
    /// faster ones behind it that overtake through lane 1, among the law's vehicles. The
    /// vehicles ahead of the law's vehicles change, and the run counts it; without the user's
    /// traffic the graph is not read from SUMO (it cannot change).
    #[test]
    fn other_traffic_changing_into_the_controlled_lane_is_counted() {
        let dir = work("user-traffic");
        two_lane_loop(&dir);
        std::fs::write(
            dir.join("mine.rou.xml"),
            r#"<routes>
    <vType id="slow" maxSpeed="3" sigma="0"/>
    <vType id="fast" maxSpeed="15" sigma="0" lcKeepRight="0" lcSpeedGain="10"/>
    <route id="u_slow" edges="e2 e3 e4 e5 e6 e7 e0 e1"/>
    <route id="u_fast" edges="e1 e2 e3 e4 e5 e6 e7 e0"/>
    <vehicle id="slow" type="slow" route="u_slow" depart="0" departLane="0" departPos="5" departSpeed="3"/>
    <flow id="fast" type="fast" route="u_fast" begin="0" end="20" number="4" departLane="0" departPos="5" departSpeed="10"/>
</routes>
"#,
        )
        .unwrap();
        let road = format!(r#"{{"type": "loop", "edges": {:?}, "lane": 1}}"#, CYCLE);
        let json = loop_json(&road, 6, 120.0, "").replace(
            r#""sumo": {"net": "out.net.xml"}"#,
            r#""sumo": {"net": "out.net.xml", "routes": ["mine.rou.xml"]}"#,
        );
        let sc = scenario(&dir, &json).unwrap();
        let run = run_scenario(&sc, &opts(&dir)).unwrap();
        let fin = run.outcome().expect("horizon reached");
        let changes = fin.totals.topology_changes.expect("watched");
        eprintln!("user traffic: {changes} topology changes");
        assert!(changes > 0, "no vehicle entered the controlled lane");
        // The same scenario alone on the road: the graph cannot change and is not read.
        // Read from SUMO anyway, nothing changes (the count is not noise of SUMO's lists),
        // and the law with its graph from SUMO drives exactly as with its fixed graph.
        let alone = scenario(&dir, &loop_json(&road, 6, 120.0, "")).unwrap();
        let fixed = run_scenario(&alone, &opts(&dir)).unwrap();
        assert_eq!(fixed.outcome().unwrap().totals.topology_changes, None);
        let road_read = syncroad_sumo::load_road(&alone).unwrap();
        let mut p = syncroad_sumo::Prepared::new(&alone, &road_read, &opts(&dir)).unwrap();
        p.request_mut().sense_graph = true;
        let run = p.run();
        assert_eq!(run.outcome().unwrap().totals.topology_changes, Some(0));
        assert_eq!(
            run.trajectory(&alone).speeds_mps,
            fixed.trajectory(&alone).speeds_mps
        );
        // A vehicle of the user's with the id of one of syncroad's: refused before SUMO starts
        // (SUMO itself would stop at start-up with "Another vehicle with the id 'v0' exists").
        std::fs::write(
            dir.join("clash.rou.xml"),
            r#"<routes><route id="mine" edges="e0 e1"/><vehicle id="v0" route="mine" depart="0"/></routes>"#,
        )
        .unwrap();
        let mut o = opts(&dir);
        o.work_dir = dir.join("clash");
        let clash = scenario(&dir, &json.replace("mine.rou.xml", "clash.rou.xml")).unwrap();
        let e = run_scenario(&clash, &o).unwrap_err().to_string();
        assert_eq!(
            e,
            format!(
                "sumo.routes[0] = {}: <vehicle id=\"v0\"> uses an id of syncroad's own vehicles (v0 … v5); rename it in your file (checked before starting SUMO)",
                dir.join("clash.rou.xml").display()
            )
        );
        assert!(!dir.join("clash/sumo.log").exists());
        // A route file that is not there is refused before SUMO starts.
        let missing = scenario(&dir, &json.replace("mine.rou.xml", "nope.rou.xml")).unwrap();
        let e = run_scenario(&missing, &opts(&dir)).unwrap_err().to_string();
        assert_eq!(
            e,
            format!(
                "sumo.routes[0] = {}: file not found (checked before starting SUMO)",
                dir.join("nope.rou.xml").display()
            )
        );
    }

    /// A slow car of the user's (`sumo.routes`, 4 m/s) starts on lane 1 of the two-lane loop
    /// and SUMO's keep-right rule moves it onto lane 0 among six law-driven vehicles at 8 m/s.
    /// With the graph taken from SUMO, the driver behind it follows it: the car is the root of
    /// every path of the graph and its speed is constant, so the delayed drivers synchronize to
    /// its 4 m/s (consensus with a leader, the paper's pinned case; the chain's loop gain
    /// 0.7 · 0.5 s lies far below π/2). On the scenario's fixed graph the law ignores the car
    /// and its vehicles keep the consensus of their own speeds, about 8 m/s, into its back.
    #[test]
    fn the_law_follows_a_car_that_changes_into_its_lane() {
        let dir = work("cut-in");
        two_lane_loop(&dir);
        slow_car(&dir);
        let road = format!(r#"{{"type": "loop", "edges": {:?}, "lane": 0}}"#, CYCLE);
        let json = loop_json(&road, 6, 240.0, "").replace(
            r#""sumo": {"net": "out.net.xml"}"#,
            r#""sumo": {"net": "out.net.xml", "routes": ["slow.rou.xml"], "fcd": true}"#,
        );
        let sc = scenario(&dir, &json).unwrap();
        let run = run_scenario(&sc, &opts(&dir)).unwrap();
        let fin = run.outcome().expect("horizon reached");
        let changes = fin.totals.topology_changes.expect("graph from SUMO");
        assert!(changes >= 1, "the slow car never entered lane 0");
        assert_eq!(fin.totals.collision_steps, 0);
        let t = run.trajectory(&sc);
        // The recorded gaps are to whoever is directly ahead: behind the car, the gap to the
        // car, as SUMO's own floating-car data has it (positions to 0.01 m, the car 5 m long),
        // not the gap across the car to the next of syncroad's vehicles.
        let (time, follower, fcd_gap) =
            gap_behind(&opts(&dir).work_dir, "slow", 5.0).expect("the car on the road's lanes");
        let k = t
            .time_s
            .iter()
            .position(|&x| (x - time).abs() < 1e-6)
            .expect("that state recorded");
        let i: usize = follower.trim_start_matches('v').parse().unwrap();
        let recorded = t.gaps(k)[i];
        eprintln!(
            "cut-in: at {time} s {follower} is {recorded} m behind the car (FCD {fcd_gap} m)"
        );
        assert!(
            (recorded - fcd_gap).abs() <= 0.02,
            "{recorded} vs {fcd_gap}"
        );
        let safety = syncroad_control::margins::GapSafety::of(&t, 0.0).expect("gaps");
        assert!(safety.min_gap_m <= recorded + 1e-9);
        let last = t.speeds(t.len() - 1);
        eprintln!("cut-in: {changes} topology changes, final speeds {last:?}");
        for (i, v) in last.iter().enumerate() {
            assert!((v - 4.0).abs() < 0.05, "vehicle {i} ends at {v} m/s");
        }
        // Every vehicle, from SUMO's summary output: the six and the car, all the time; their
        // mean speed is the trajectory's six with the car's constant 4 m/s, up to the 0.01 m/s
        // SUMO prints.
        let all = all_vehicles(&run, &sc);
        assert_eq!((all.vehicles_max, all.vehicles_mean), (7, 7.0));
        let mean: f64 = (0..t.len())
            .map(|k| (t.speeds(k).iter().sum::<f64>() + 4.0) / 7.0)
            .sum::<f64>()
            / t.len() as f64;
        let got = all.mean_speed_mps.unwrap();
        eprintln!("cut-in: all vehicles' mean speed {got} m/s, trajectory and car {mean} m/s");
        assert!((got - mean).abs() < 0.01, "{got} vs {mean}");
        assert_eq!(all.collisions, 0);
        // The fixed graph: nobody follows the car.
        let road_read = syncroad_sumo::load_road(&sc).unwrap();
        let mut o = opts(&dir);
        o.work_dir = dir.join("fixed");
        let mut p = syncroad_sumo::Prepared::new(&sc, &road_read, &o).unwrap();
        p.request_mut().sense_graph = false;
        // The law alone, as the paper has it: with SUMO's checks (the default with other
        // traffic) SUMO's safe speed would brake the six behind the car for them.
        p.request_mut().speed_mode = 32;
        let fixed = p.run();
        let ft = fixed.trajectory(&sc);
        let fastest = ft.speeds(ft.len() - 1).iter().copied().fold(0.0, f64::max);
        let hit = fixed.outcome().map_or(true, |f| {
            f.totals.collision_steps > 0 || f.totals.teleports > 0
        });
        assert!(
            hit || fastest > 6.0,
            "the fixed graph also slowed to {fastest} m/s without a collision"
        );
    }

    /// syncroad's own vehicles of `routes` (the routes file of a run) as the user's: vehicles
    /// `cav0`…, of a vType `cav` with syncroad's values (`cav_length` long), each on a route of
    /// one lap from its edge, written back to front; and the slow car's lines.
    fn as_users_own(routes: &str, cav_length: &str) -> String {
        let mut out = vec!["<routes>".to_string()];
        let mut vehicles = Vec::new();
        for l in routes.lines() {
            if l.contains("<vType id=\"t0\"") {
                let l = l.replace("id=\"t0\"", "id=\"cav\"");
                let at = l.find("length=\"").unwrap() + 8;
                let end = at + l[at..].find('"').unwrap();
                out.push(format!("{}{cav_length}{}", &l[..at], &l[end..]));
            } else if let Some(rest) = l.trim().strip_prefix("<route id=\"r") {
                let k = &rest[..rest.find('"').unwrap()];
                let e = rest.find("edges=\"").unwrap() + 7;
                let edges = &rest[e..e + rest[e..].find('"').unwrap()];
                out.push(format!(r#"    <route id="u{k}" edges="{edges}"/>"#));
            } else if l.contains("<vehicle id=\"v") {
                let l = l.replacen("<vehicle id=\"v", "<vehicle id=\"cav", 1);
                vehicles.push(
                    l.replace("type=\"t0\"", "type=\"cav\"")
                        .replace("route=\"r", "route=\"u"),
                );
            }
        }
        vehicles.reverse();
        out.extend(vehicles);
        out.push(r#"    <vType id="slow" maxSpeed="4" sigma="0"/>"#.into());
        out.push(r#"    <route id="u_slow" edges="e4 e5 e6 e7 e0 e1 e2 e3" repeat="5"/>"#.into());
        out.push(r#"    <vehicle id="slow" type="slow" route="u_slow" depart="0" departLane="1" departPos="20" departSpeed="4"/>"#.into());
        out.push("</routes>\n".into());
        out.join("\n")
    }

    /// The law drives the user's own vehicles (`sumo.controlled`): six of type `cav` in the
    /// user's route file, placed where syncroad placed its own in a run of the same scenario,
    /// written back to front, each on a route of one lap, beside the slow car that changes
    /// into their lane. They are bound front to back and keep circling for several laps: the
    /// run is the run of syncroad's own vehicles, speed for speed. Too many of them for the
    /// scenario is refused before SUMO starts; a length that is not the scenario's is
    /// refused by the worker, which sees SUMO's vehicles.
    #[test]
    fn the_law_drives_the_users_own_vehicles_chosen_by_type() {
        let dir = work("controlled");
        two_lane_loop(&dir);
        slow_car(&dir);
        let road = format!(r#"{{"type": "loop", "edges": {:?}, "lane": 0}}"#, CYCLE);
        let base = loop_json(&road, 6, 400.0, "");
        let json = base.replace(
            r#""sumo": {"net": "out.net.xml"}"#,
            r#""sumo": {"net": "out.net.xml", "routes": ["slow.rou.xml"]}"#,
        );
        let sc = scenario(&dir, &json).unwrap();
        let own = run_scenario(&sc, &opts(&dir)).unwrap();
        let own_fin = own.outcome().expect("horizon reached");
        let routes = std::fs::read_to_string(dir.join("run/routes.rou.xml")).unwrap();
        std::fs::write(dir.join("cav.rou.xml"), as_users_own(&routes, "5")).unwrap();
        let users = base.replace(
            r#""sumo": {"net": "out.net.xml"}"#,
            r#""sumo": {"net": "out.net.xml", "routes": ["cav.rou.xml"], "controlled": {"vtype": "cav"}}"#,
        );
        let sc_users = scenario(&dir, &users).unwrap();
        let mut o = opts(&dir);
        o.work_dir = dir.join("users");
        let run = run_scenario(&sc_users, &o).unwrap();
        let fin = run
            .outcome()
            .expect("horizon reached: the vehicles kept circling");
        let facts = run.output(&sc_users).sumo.unwrap();
        let front_to_back: Vec<String> = (0..6).map(|i| format!("cav{i}")).collect();
        let controlled = facts.controlled.clone().expect("the user's own vehicles");
        assert_eq!(controlled.vehicles, front_to_back);
        assert_eq!(controlled.later, Some(0));
        let (a, b) = (own.trajectory(&sc), run.trajectory(&sc_users));
        let n = b.positions_m.len();
        let laps = b.positions_m[n - 1] - b.positions_m[5];
        eprintln!(
            "controlled: {laps:.1} m driven, {:?} topology changes",
            fin.totals.topology_changes
        );
        assert!(laps > 1.5 * facts.road_length_m, "only {laps} m driven");
        assert_eq!(a.speeds_mps, b.speeds_mps);
        // Positions are SUMO's lane positions summed along the loop, against the layout's
        // placement: equal up to the rounding of the two sums.
        let dq = worst_speed_difference(&a.positions_m, &b.positions_m);
        let dg = worst_speed_difference(&a.gaps_m, &b.gaps_m);
        eprintln!("controlled: positions within {dq:.1e} m, gaps within {dg:.1e} m");
        assert!(dq < 1e-9 && dg < 1e-9, "{dq} {dg}");
        assert_eq!(fin.totals.topology_changes, own_fin.totals.topology_changes);
        assert!(fin.totals.topology_changes.unwrap() >= 1);
        // syncroad inserted none of its own.
        assert!(!std::fs::read_to_string(dir.join("users/routes.rou.xml"))
            .unwrap()
            .contains("<vehicle"));
        // Before SUMO starts: six of them for a scenario of five.
        let five = scenario(&dir, &users.replace(r#""vehicles": 6"#, r#""vehicles": 5"#)).unwrap();
        let err = syncroad_sumo::check_run(&five, &load_road(&five).unwrap(), &o)
            .unwrap_err()
            .to_string();
        assert_eq!(
            err,
            r#"sumo.controlled = {"vtype":"cav"}: 6 of your vehicles depart at t = 0 and match (cav5 … cav0), but the run drives 5 vehicles (`vehicles` = 5): give as many vehicles in the scenario as your files start with (checked before starting SUMO)"#
        );
        // A SUMO driver (as compare's baselines give) does not take a chosen vehicle.
        let mut with_drivers = o.clone();
        with_drivers.drivers =
            vec![Some(syncroad_control::drive::SumoDriver::parse("drivers", "idm").unwrap()); 6];
        let err =
            syncroad_sumo::check_run(&sc_users, &load_road(&sc_users).unwrap(), &with_drivers)
                .unwrap_err()
                .to_string();
        assert!(
            err.contains("no SUMO driver (`drivers`, `mixed`, compare's baselines) takes a vehicle of the run"),
            "{err}"
        );
        // A chosen vehicle departing later, onto the law's lane: counted, driven by SUMO.
        let later = as_users_own(&routes, "5").replace(
            "</routes>",
            r#"    <vehicle id="cav9" type="cav" route="u0" depart="20" departLane="0" departPos="free"/>
</routes>"#,
        );
        std::fs::write(dir.join("cav.rou.xml"), later).unwrap();
        o.work_dir = dir.join("later");
        let short_horizon = scenario(
            &dir,
            &users.replace(r#""horizon_s": 400"#, r#""horizon_s": 60"#),
        )
        .unwrap();
        let run = run_scenario(&short_horizon, &o).unwrap();
        run.outcome().expect("horizon reached");
        let c = run.output(&short_horizon).sumo.unwrap().controlled.unwrap();
        assert_eq!((c.vehicles.len(), c.later), (6, Some(1)));
        // In the worker: a vehicle type of another length.
        std::fs::write(dir.join("cav.rou.xml"), as_users_own(&routes, "4")).unwrap();
        o.work_dir = dir.join("short");
        let short = run_scenario(&sc_users, &o).unwrap();
        let msg = short.failure().expect("refused").to_string();
        assert!(
            msg.contains(r#"sumo.controlled = {"vtype":"cav"}: vehicle cav0 (the law's vehicle 0) is 4 m long, but the scenario's vehicles are 5 m (sumo.length_m)"#),
            "{msg}"
        );
    }

    /// A whole SUMO configuration (`sumo.config`) in a folder of its own, naming the network and
    /// the slow car's route file relative to itself, with a step length and an output of its
    /// own: the run is the run of the same files named one by one (`sumo.net`, `sumo.routes`),
    /// speed for speed; its other options are listed as ignored and its output is not
    /// written. A scenario naming the network in both places is refused before SUMO starts.
    #[test]
    fn a_sumo_config_runs_as_its_files_named_one_by_one() {
        let dir = work("config");
        two_lane_loop(&dir);
        slow_car(&dir);
        std::fs::create_dir_all(dir.join("cfg")).unwrap();
        std::fs::write(
            dir.join("cfg/track.sumocfg"),
            r#"<?xml version="1.0" encoding="UTF-8"?>
<configuration>
    <input>
        <net-file value="../out.net.xml"/>
        <route-files value="../slow.rou.xml"/>
    </input>
    <time>
        <step-length value="1"/>
    </time>
    <output>
        <fcd-output value="fcd.xml"/>
    </output>
</configuration>
"#,
        )
        .unwrap();
        let road = format!(r#"{{"type": "loop", "edges": {:?}, "lane": 0}}"#, CYCLE);
        let files = loop_json(&road, 6, 60.0, "").replace(
            r#""sumo": {"net": "out.net.xml"}"#,
            r#""sumo": {"net": "out.net.xml", "routes": ["slow.rou.xml"]}"#,
        );
        let config = loop_json(&road, 6, 60.0, "").replace(
            r#""sumo": {"net": "out.net.xml"}"#,
            r#""sumo": {"config": "cfg/track.sumocfg"}"#,
        );
        let by_files = scenario(&dir, &files).unwrap();
        let by_config = scenario(&dir, &config).unwrap();
        assert_eq!(
            by_config.sumo().net(),
            Some(dir.join("cfg/../out.net.xml").as_path())
        );
        assert_eq!(
            by_config.sumo().config_ignored(),
            ["step-length = 1", "fcd-output = fcd.xml"]
        );
        let a = run_scenario(&by_files, &opts(&dir)).unwrap();
        let mut o = opts(&dir);
        o.work_dir = dir.join("by-config");
        let b = run_scenario(&by_config, &o).unwrap();
        assert!(b
            .outcome()
            .expect("horizon reached")
            .totals
            .topology_changes
            .is_some());
        assert_eq!(
            a.trajectory(&by_files).speeds_mps,
            b.trajectory(&by_config).speeds_mps
        );
        assert!(!dir.join("cfg/fcd.xml").exists() && !dir.join("by-config/fcd.xml").exists());
        let both = config.replace(
            r#""config": "cfg/track.sumocfg""#,
            r#""config": "cfg/track.sumocfg", "net": "out.net.xml""#,
        );
        assert_eq!(
            scenario(&dir, &both).unwrap_err(),
            format!(
                "sumo.net = {}: sumo.config {} names a network too (net-file {}); give the network once, in either",
                dir.join("out.net.xml").display(),
                dir.join("cfg/track.sumocfg").display(),
                dir.join("cfg/../out.net.xml").display()
            )
        );
    }

    /// A detector of the user's own (`sumo.additional`) at 10 m into lane e0_0 counts
    /// exactly the crossings of that point that the trajectory shows: SUMO drives the lane
    /// sequence syncroad measured, and the trajectory's loop coordinate is SUMO's (up to the
    /// layout's turn along the loop, which keeps departures off junction lanes, here nonzero).
    #[test]
    fn an_additional_detector_counts_the_crossings_the_trajectory_shows() {
        let dir = work("additional");
        two_lane_loop(&dir);
        std::fs::write(
            dir.join("mine.add.xml"),
            r#"<additional>
    <inductionLoop id="mine" lane="e0_0" pos="10" period="1000" file="mine-e1.xml"/>
</additional>
"#,
        )
        .unwrap();
        // Lane 0 and a fleet size whose even spacing puts a front bumper deep inside the
        // 18 m junction lane at n1: the layout is turned along the loop.
        let road = format!(r#"{{"type": "loop", "edges": {:?}, "lane": 0}}"#, CYCLE);
        let with_detector = |n: usize| {
            loop_json(&road, n, 100.0, "").replace(
                r#""sumo": {"net": "out.net.xml"}"#,
                r#""sumo": {"net": "out.net.xml", "additional": ["mine.add.xml"]}"#,
            )
        };
        let n = (8..40)
            .find(|&n| {
                let sc = scenario(&dir, &with_detector(n)).unwrap();
                let road = load_road(&sc).unwrap();
                let p = syncroad_sumo::Prepared::new(&sc, &road, &opts(&dir)).unwrap();
                p.request().layout.ring_offset_m > 0.0
            })
            .expect("a fleet whose layout is turned");
        let json = with_detector(n);
        let sc = scenario(&dir, &json).unwrap();
        let run = run_scenario(&sc, &opts(&dir)).unwrap();
        run.outcome().expect("horizon reached");
        // Its output lands in the run's folder (`outputs/`), not beside the additional file.
        assert!(!dir.join("mine-e1.xml").exists());
        let written: Vec<_> = std::fs::read_dir(dir.join("run/outputs"))
            .unwrap()
            .flatten()
            .map(|e| e.path())
            .collect();
        assert_eq!(written.len(), 1, "{written:?}");
        assert!(written[0].to_string_lossy().ends_with("mine-e1.xml"));
        let out = std::fs::read_to_string(&written[0]).unwrap();
        let counted: i64 = out
            .split("nVehContrib=\"")
            .skip(1)
            .map(|s| s[..s.find('"').unwrap()].parse::<i64>().unwrap())
            .sum();
        let lay = &run.request.layout;
        let ring = lay.road.length_m();
        // e0 is the loop's first edge: 10 m into it is SUMO's coordinate 10.
        let x = (10.0 - lay.ring_offset_m).rem_euclid(ring);
        let t = run.trajectory(&sc);
        let k = t.len() - 1;
        let lap = |q: f64| ((q + 5.0 - x) / ring).floor() as i64;
        let crossings: i64 = (0..n)
            .map(|i| lap(t.positions_m[k * n + i]) - lap(t.positions_m[i]))
            .sum();
        // SUMO also counts a vehicle that departs on top of the detector (it enters there).
        let on_it = (0..n)
            .filter(|&i| (t.positions_m[i] - x).rem_euclid(ring) > ring - 5.0)
            .count() as i64;
        let crossings = crossings + on_it;
        eprintln!("detector: {counted} passages, trajectory: {crossings} crossings, layout turned by {:.3} m", lay.ring_offset_m);
        assert!(crossings > n as i64, "{crossings}");
        assert_eq!(counted, crossings);
        let missing = scenario(&dir, &json.replace("mine.add.xml", "nope.add.xml")).unwrap();
        let e = run_scenario(&missing, &opts(&dir)).unwrap_err().to_string();
        assert!(e.starts_with("sumo.additional[0] = "), "{e}");
    }

    /// A small OpenStreetMap file (a one-way two-lane circuit of six nodes with a side road)
    /// imported by netconvert: the cycle through its first edge is found, measured as sumolib
    /// measures it, and driven in SUMO as the native simulator drives it.
    #[test]
    fn an_openstreetmap_circuit_runs_like_the_native_simulator() {
        let dir = work("osm");
        let mut osm =
            String::from("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<osm version=\"0.6\">\n");
        let (lat0, lon0) = (52.0, 5.0);
        for i in 0..6 {
            let a = 2.0 * std::f64::consts::PI * i as f64 / 6.0;
            osm += &format!(
                "  <node id=\"{}\" lat=\"{:.7}\" lon=\"{:.7}\" version=\"1\"/>\n",
                i + 1,
                lat0 + 0.0012 * a.sin(),
                lon0 + 0.002 * a.cos()
            );
        }
        osm += "  <node id=\"7\" lat=\"52.0030\" lon=\"5.0040\" version=\"1\"/>\n";
        osm += "  <way id=\"100\" version=\"1\">\n";
        for n in [1, 2, 3, 4, 5, 6, 1] {
            osm += &format!("    <nd ref=\"{n}\"/>\n");
        }
        osm += "    <tag k=\"highway\" v=\"primary\"/>\n    <tag k=\"oneway\" v=\"yes\"/>\n    <tag k=\"lanes\" v=\"2\"/>\n    <tag k=\"maxspeed\" v=\"50\"/>\n  </way>\n";
        osm += "  <way id=\"200\" version=\"1\">\n    <nd ref=\"2\"/>\n    <nd ref=\"7\"/>\n    <tag k=\"highway\" v=\"residential\"/>\n  </way>\n</osm>\n";
        std::fs::write(dir.join("circuit.osm"), osm).unwrap();
        let net = netconvert(&dir, &["--osm-files", "circuit.osm"]);
        let text = std::fs::read_to_string(&net).unwrap();
        let first = text
            .split("<edge id=\"")
            .skip(1)
            .map(|s| &s[..s.find('"').unwrap()])
            .find(|id| id.starts_with("100#") || *id == "100")
            .expect("an edge of the circuit")
            .to_string();
        let road = format!(r#"{{"type": "loop", "through": "{first}", "lane": 0}}"#);
        let sc = scenario(&dir, &loop_json(&road, 8, 60.0, "")).unwrap();
        let m = sc.measured_road().unwrap().clone();
        assert!(m.edges.len() >= 2, "{:?}", m.edges);
        assert!(
            m.edges.iter().all(|e| e.starts_with("100")),
            "{:?}",
            m.edges
        );
        let edges: Vec<&str> = m.edges.iter().map(String::as_str).collect();
        assert_relative_eq!(
            m.length_m,
            sumolib_length(&net, &edges, 0, true),
            epsilon = 1e-9
        );
        let run = run_scenario(&sc, &opts(&dir)).unwrap();
        run.outcome().expect("horizon reached");
        let native = simulate(&sc, NativeOptions::default()).trajectory;
        let worst = worst_speed_difference(&native.speeds_mps, &run.trajectory(&sc).speeds_mps);
        eprintln!("OSM circuit: largest SUMO-native speed difference {worst:.2e} m/s");
        assert!(worst < 1e-9, "largest speed difference {worst} m/s");
    }
}

/// A single-lane loop of 8 edges around an octagon (100 m radius, 15 m/s) crossed at its top
/// node n2 by a side road `in` → `out` (north to the loop's inside); n2 is a traffic light
/// (netconvert's static program), so the loop's vehicles on e1 meet red while the crossing
/// road has green.
fn signalled_loop(dir: &Path) -> PathBuf {
    let mut nod = String::from("<nodes>\n");
    for i in 0..8 {
        let a = 2.0 * std::f64::consts::PI * i as f64 / 8.0;
        let kind = if i == 2 {
            r#" type="traffic_light""#
        } else {
            ""
        };
        nod += &format!(
            "  <node id=\"n{i}\" x=\"{:.3}\" y=\"{:.3}\"{kind}/>\n",
            100.0 * a.cos(),
            100.0 * a.sin()
        );
    }
    nod += "  <node id=\"north\" x=\"0\" y=\"250\"/>\n  <node id=\"inner\" x=\"0\" y=\"20\"/>\n</nodes>\n";
    let mut edg = String::from("<edges>\n");
    for i in 0..8 {
        edg += &format!(
            "  <edge id=\"e{i}\" from=\"n{i}\" to=\"n{}\" numLanes=\"1\" speed=\"15\"/>\n",
            (i + 1) % 8
        );
    }
    edg += "  <edge id=\"in\" from=\"north\" to=\"n2\" numLanes=\"1\" speed=\"15\"/>\n";
    edg += "  <edge id=\"out\" from=\"n2\" to=\"inner\" numLanes=\"1\" speed=\"15\"/>\n</edges>\n";
    std::fs::write(dir.join("tls.nod.xml"), nod).unwrap();
    std::fs::write(dir.join("tls.edg.xml"), edg).unwrap();
    netconvert(
        dir,
        &["--node-files", "tls.nod.xml", "--edge-files", "tls.edg.xml"],
    )
}

mod signals {
    use super::*;

    fn run_with(dir: &Path, safety: Option<&str>) -> (f64, syncroad_sumo::SumoRun) {
        run_law(dir, safety, None)
    }

    /// The loop's run under `safety` (the default when `None`), the model's law or the
    /// registry's `law`; its slowest speed.
    fn run_law(
        dir: &Path,
        safety: Option<&str>,
        law: Option<serde_json::Value>,
    ) -> (f64, syncroad_sumo::SumoRun) {
        let road = r#"{"type": "loop", "edges": ["e0", "e1", "e2", "e3", "e4", "e5", "e6", "e7"]}"#;
        let mut json: serde_json::Value =
            serde_json::from_str(&loop_json(road, 10, 200.0, "")).unwrap();
        if let Some(s) = safety {
            json["safety"] = serde_json::json!(s);
        }
        if let Some(l) = law {
            json["controller"] = l;
        }
        let sc = scenario(dir, &json.to_string()).unwrap();
        let mut o = opts(dir);
        o.work_dir = dir.join(format!(
            "{}-{}",
            safety.unwrap_or("default"),
            json["controller"]["rust"]
                .as_str()
                .unwrap_or("python-or-law")
        ));
        let run = run_scenario(&sc, &o).unwrap();
        let slowest = run
            .trajectory(&sc)
            .speeds_mps
            .iter()
            .fold(f64::INFINITY, |m, v| m.min(*v));
        (slowest, run)
    }

    /// A Python controller of the user's sees the traffic light ahead in its observation:
    /// with no safety layer under it (so SUMO would let it drive through red), it stops before
    /// red and yellow lights by itself, keeping a 1 s gap behind whoever stopped, and nobody
    /// collides.
    #[test]
    fn a_python_controller_stops_for_red_from_its_observation() {
        let dir = work("py-signals");
        signalled_loop(&dir);
        std::fs::write(
            dir.join("stop_for_red.py"),
            r#"import numpy as np

class StopForRed:
    def __init__(self):
        self.saw_red = False

    def step(self, obs):
        d = obs.signal_distance_m
        red = (obs.signal_stop > 0) & np.isfinite(d)
        self.saw_red = self.saw_red or bool(red.any())
        v = np.full(len(obs.ids), 8.0)
        # Stop 2 m before the line from 3 m/s^2, and keep 1 s behind the one ahead.
        v = np.where(red & (d < 40.0), np.minimum(v, np.sqrt(6.0 * np.maximum(d - 2.0, 0.0))), v)
        v = np.minimum(v, np.maximum(obs.gap_m - 2.0, 0.0) / 1.0)
        if obs.step == 1999 and not self.saw_red:
            raise RuntimeError("no red light in 200 s")
        return v
"#,
        )
        .unwrap();
        let law = serde_json::json!({"python": dir.join("stop_for_red.py:StopForRed").display().to_string()});
        let (slowest, run) = run_law(&dir, Some("off"), Some(law));
        assert_eq!(run.request.speed_mode, 32);
        let fin = run.outcome().expect("horizon reached");
        assert!(
            slowest < 0.1,
            "slowest {slowest} m/s: nobody stopped for red"
        );
        assert_eq!(fin.totals.collision_steps, 0);
    }

    /// A law that wants 25 m/s on the loop's 15 m/s lanes: with the layer off the vehicles
    /// drive 25 m/s; syncroad's filter holds every command to the road's limit (and SUMO's
    /// checks hold them to it too).
    #[test]
    fn the_filter_and_sumos_checks_keep_the_speed_limit() {
        let dir = work("speed-limit");
        signalled_loop(&dir);
        let fast =
            serde_json::json!({"rust": "constant-speed", "params": {"target_speed_mps": 25.0}});
        let fastest = |safety| {
            let (_, run) = run_law(&dir, Some(safety), Some(fast.clone()));
            let top = run
                .worker
                .rows
                .speeds_mps
                .iter()
                .copied()
                .fold(0.0, f64::max);
            (top, run)
        };
        let (off, _) = fastest("off");
        assert!(off > 24.0, "with the layer off: {off} m/s");
        let (filtered, run) = fastest("filter");
        assert!(filtered <= 15.0 + 1e-9, "under the filter: {filtered} m/s");
        let fin = run.outcome().expect("horizon reached");
        assert_eq!(fin.totals.collision_steps, 0);
        let (sumo, _) = fastest("sumo");
        assert!(sumo <= 15.0 + 1e-6, "under SUMO's checks: {sumo} m/s");
    }

    /// The law's vehicles on a loop through a traffic light: with the safety layer off they
    /// never stop (the law keeps them near 8 m/s through red); under the default layer, which
    /// is SUMO's checks because the network has a traffic light, they stop at the red light,
    /// SUMO overrides the law's commands, and nobody collides.
    #[test]
    fn the_laws_vehicles_stop_for_red_under_the_default_layer_and_not_with_it_off() {
        let dir = work("signals");
        let net = signalled_loop(&dir);
        assert!(std::fs::read_to_string(&net).unwrap().contains("<tlLogic "));
        let (slowest_off, off) = run_with(&dir, Some("off"));
        assert_eq!(off.request.speed_mode, 32);
        assert!(
            slowest_off > 4.0,
            "with the layer off: slowest {slowest_off} m/s"
        );
        let (slowest, run) = run_with(&dir, None);
        assert_eq!(run.request.speed_mode, 25, "the default is SUMO's checks");
        let fin = run.outcome().expect("horizon reached");
        assert!(slowest < 0.1, "under SUMO's checks: slowest {slowest} m/s");
        assert!(fin.totals.overrides > 0);
        assert_eq!(fin.totals.collision_steps, 0);
        assert_eq!(fin.totals.teleports, 0);
        // syncroad's filter does the car following; SUMO still brakes them for red (speed
        // mode 48), and the followers' filter keeps them behind the stopped ones.
        let (slowest, run) = run_with(&dir, Some("filter"));
        assert_eq!(run.request.speed_mode, 48);
        let fin = run.outcome().expect("horizon reached");
        assert!(slowest < 0.1, "under the filter: slowest {slowest} m/s");
        assert_eq!(fin.totals.collision_steps, 0);
        assert_eq!(fin.totals.teleports, 0);
    }
}

mod routes {
    use super::*;

    /// The CACC platoon behind its braking leader on lane 1 of a three-lane highway of four
    /// edges: the route is measured as sumolib measures it, and SUMO gives the native
    /// simulator's speeds to 1e-9 m/s across the junctions; so it does when the platoon is
    /// the user's own vehicles, chosen by an id pattern (`sumo.controlled`).
    #[test]
    fn a_platoon_on_a_three_lane_route_follows_the_native_simulator() {
        let dir = work("platoon");
        let net = highway(&dir, false, false);
        let text = std::fs::read_to_string(
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenarios/platoon-cacc.json"),
        )
        .unwrap();
        let mut file: serde_json::Value = serde_json::from_str(&text).unwrap();
        file["horizon_s"] = 40.0.into();
        file["road"] =
            serde_json::json!({"type": "route", "edges": ["h0", "h1", "h2", "h3"], "lane": 1});
        file["sumo"] = serde_json::json!({"net": "out.net.xml"});
        let sc = scenario(&dir, &file.to_string()).unwrap();
        let reference = sumolib_length(&net, &["h0", "h1", "h2", "h3"], 1, false);
        assert_relative_eq!(
            sc.measured_road().unwrap().length_m,
            reference,
            epsilon = 1e-9
        );
        let run = run_scenario(&sc, &opts(&dir)).unwrap();
        let fin = run.outcome().expect("horizon reached");
        assert_eq!(fin.totals.collision_steps, 0);
        let native = simulate(&sc, NativeOptions::default()).trajectory;
        let worst = worst_speed_difference(&native.speeds_mps, &run.trajectory(&sc).speeds_mps);
        eprintln!("3-lane route platoon: largest SUMO-native speed difference {worst:.2e} m/s");
        assert!(worst < 1e-9, "largest speed difference {worst} m/s");
        // The same platoon as the user's own vehicles `p0` (the leader) … `p8`, chosen by an
        // id pattern: bound front to back, the leader follows its profile, and SUMO still
        // gives the native simulator's speeds.
        let mut routes = std::fs::read_to_string(dir.join("run/routes.rou.xml"))
            .unwrap()
            .replace("<vType id=\"t", "<vType id=\"ut")
            .replace("type=\"t", "type=\"ut")
            .replace("<route id=\"r", "<route id=\"ur")
            .replace("route=\"r", "route=\"ur")
            .replace("<vehicle id=\"leader\"", "<vehicle id=\"p0\"");
        let n = sc.vehicles();
        for k in (0..n).rev() {
            routes = routes.replace(
                &format!("<vehicle id=\"v{k}\""),
                &format!("<vehicle id=\"p{}\"", k + 1),
            );
        }
        std::fs::write(dir.join("platoon.rou.xml"), routes).unwrap();
        let mut own = file.clone();
        own["sumo"] = serde_json::json!({"net": "out.net.xml", "routes": ["platoon.rou.xml"],
                                         "controlled": {"id": "p\\d+"}});
        // The law's own dynamics, to compare with the native simulator: no safety layer (the
        // user's routes would put the CACC platoon's short gaps under SUMO's checks).
        own["safety"] = "off".into();
        let own = scenario(&dir, &own.to_string()).unwrap();
        let mut o = opts(&dir);
        o.work_dir = dir.join("own");
        let run = run_scenario(&own, &o).unwrap();
        run.outcome().expect("horizon reached");
        let c = run.output(&own).sumo.unwrap().controlled.unwrap();
        let ids: Vec<String> = (0..=n).map(|k| format!("p{k}")).collect();
        assert_eq!(c.vehicles, ids);
        let worst = worst_speed_difference(&native.speeds_mps, &run.trajectory(&own).speeds_mps);
        eprintln!("the user's own platoon: largest SUMO-native speed difference {worst:.2e} m/s");
        assert!(worst < 1e-9, "largest speed difference {worst} m/s");
        // The horizon check uses the route's length: 2 km do not hold 400 s at 25 m/s.
        file["horizon_s"] = 400.0.into();
        let long = scenario(&dir, &file.to_string()).unwrap();
        let err = run_scenario(&long, &opts(&dir)).unwrap_err().to_string();
        assert!(
            err.contains(&format!("is {:.1} m long but the run needs", reference)),
            "{err}"
        );
    }
}

/// Routes whose lane changes from edge to edge, and vehicles of another class.
mod open_roads {
    use super::*;

    fn platoon_on(road: serde_json::Value, sumo: serde_json::Value) -> serde_json::Value {
        let text = std::fs::read_to_string(
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenarios/platoon-cacc.json"),
        )
        .unwrap();
        let mut file: serde_json::Value = serde_json::from_str(&text).unwrap();
        file["horizon_s"] = 30.0.into();
        file["road"] = road;
        file["sumo"] = sumo;
        file
    }

    /// Through the on-ramp's merge the highway's lane 0 continues as lane 1 of `h1`: one lane
    /// index for the whole route is refused with the lanes that do connect, `"follow"` and the
    /// list `[0, 1, 1]` take the connections, the route is measured along those lanes as
    /// sumolib measures it, and in SUMO the CACC platoon drives across the merge onto lane 1
    /// with the native simulator's speeds to 1e-9 m/s (the positions along the lanes actually
    /// driven are the native road's).
    #[test]
    fn a_route_through_an_on_ramp_merge_follows_the_connections() {
        let dir = work("on-ramp");
        let net = on_ramp(&dir);
        let sumo = serde_json::json!({"net": "out.net.xml"});
        let road = |lane: serde_json::Value| serde_json::json!({"type": "route", "edges": ["h0", "h1", "h2"], "lane": lane});
        let e = scenario(&dir, &platoon_on(road(0.into()), sumo.clone()).to_string()).unwrap_err();
        assert_eq!(
            e,
            format!("road.edges[0] `h0` → road.edges[1] `h1`: {} connects no lane 0 of `h0` to lane 0 of `h1`; its connections to `h1` join lanes 0→1, 1→2 (a route may change lanes where the connections do: road.lane = \"follow\", or one lane index per edge)", net.display())
        );
        let reference = sumolib_length_on(&net, &["h0", "h1", "h2"], &[0, 1, 1], false);
        let with_fcd = serde_json::json!({"net": "out.net.xml", "fcd": true});
        let follow = scenario(
            &dir,
            &platoon_on(road("follow".into()), with_fcd).to_string(),
        )
        .unwrap();
        let m = follow.measured_road().unwrap();
        assert_eq!(m.lanes, [0, 1, 1]);
        assert_relative_eq!(m.length_m, reference, epsilon = 1e-9);
        let listed = platoon_on(road(serde_json::json!([0, 1, 1])), sumo.clone());
        let listed = scenario(&dir, &listed.to_string()).unwrap();
        assert_eq!(listed.measured_road(), follow.measured_road());
        // From the ramp, "follow" takes the acceleration lane.
        let from_ramp =
            serde_json::json!({"type": "route", "edges": ["ramp", "h1", "h2"], "lane": "follow"});
        let ramp = scenario(&dir, &platoon_on(from_ramp, sumo.clone()).to_string()).unwrap();
        assert_eq!(ramp.measured_road().unwrap().lanes, [0, 0, 0]);
        // A list of the wrong length, and a list whose lanes do not connect.
        let e = scenario(
            &dir,
            &platoon_on(road(serde_json::json!([0, 1])), sumo.clone()).to_string(),
        )
        .unwrap_err();
        assert_eq!(e, "road.lane = [0, 1]: gives 2 lane(s) for 3 edge(s): one lane index per edge of road.edges, one index for all, or \"follow\"");
        let e = scenario(
            &dir,
            &platoon_on(road(serde_json::json!([0, 1, 2])), sumo.clone()).to_string(),
        )
        .unwrap_err();
        assert!(
            e.starts_with("road.edges[1] `h1` → road.edges[2] `h2`:") && e.contains("connects no lane 1 of `h1` to lane 2 of `h2`; its connections to `h2` join lanes 0→0, 1→1, 2→2"),
            "{e}"
        );
        // No lane sequence at all: the message says where the search stopped.
        let nowhere =
            serde_json::json!({"type": "route", "edges": ["h0", "ramp"], "lane": "follow"});
        let e = scenario(&dir, &platoon_on(nowhere, sumo.clone()).to_string()).unwrap_err();
        assert_eq!(
            e,
            format!("road.lane = \"follow\": no lane that the route reaches on road.edges[0] `h0` leads on to road.edges[1] `ramp` through {}'s connections for class passenger; `h0` does not lead to `ramp` at all; it leads to `h1`", net.display())
        );
        // In SUMO, across the merge.
        let run = run_scenario(&follow, &opts(&dir)).unwrap();
        let fin = run.outcome().expect("horizon reached");
        assert_eq!(fin.totals.collision_steps, 0);
        let routes = std::fs::read_to_string(dir.join("run/routes.rou.xml")).unwrap();
        assert!(routes.contains(r#"edges="h0 h1 h2""#), "{routes}");
        // SUMO's own record: every vehicle drove lane 0 of h0, then lane 1 of h1, no other.
        let fcd = std::fs::read_to_string(dir.join("run/fcd.xml")).unwrap();
        let lanes: std::collections::BTreeSet<&str> = fcd
            .split("lane=\"")
            .skip(1)
            .filter_map(|t| t.split('"').next())
            .filter(|l| !l.starts_with(':'))
            .collect();
        assert_eq!(
            lanes,
            ["h0_0", "h1_1"].into_iter().collect(),
            "lanes driven"
        );
        let native = simulate(&follow, NativeOptions::default()).trajectory;
        let worst = worst_speed_difference(&native.speeds_mps, &run.trajectory(&follow).speeds_mps);
        eprintln!("platoon across the on-ramp merge: largest SUMO-native speed difference {worst:.2e} m/s");
        assert!(worst < 1e-9, "largest speed difference {worst} m/s");
    }

    /// Human traffic entering from the on-ramp while the platoon drives the highway: the
    /// inflow's vehicles enter, SUMO routes them across the merge and they leave at the end of
    /// `h1`, counted by SUMO's summary (never more than entered: a vehicle every 4 s); the law
    /// senses them as other traffic; nobody collides. Every inflow error is found before SUMO
    /// starts and names the field.
    #[test]
    fn an_inflow_enters_at_the_ramp_and_leaves_at_its_edge() {
        let dir = work("inflow");
        let net = on_ramp(&dir);
        let road =
            serde_json::json!({"type": "route", "edges": ["h0", "h1", "h2"], "lane": "follow"});
        let inflow = |extra: serde_json::Value| {
            let mut f = serde_json::json!({"from": "ramp", "to": "h1", "vehs_per_hour": 900});
            for (k, v) in extra.as_object().unwrap() {
                f[k] = v.clone();
            }
            let mut file = platoon_on(
                road.clone(),
                serde_json::json!({"net": "out.net.xml", "inflows": [f]}),
            );
            file["horizon_s"] = 40.0.into();
            file
        };
        let sc = scenario(&dir, &inflow(serde_json::json!({})).to_string()).unwrap();
        let run = run_scenario(&sc, &opts(&dir)).unwrap();
        run.outcome().expect("horizon reached");
        let flows = std::fs::read_to_string(dir.join("run/inflows.rou.xml")).unwrap();
        assert!(
            flows.contains(r#"from="ramp" to="h1" begin="0" end="40" vehsPerHour="900""#),
            "{flows}"
        );
        let all = all_vehicles(&run, &sc);
        let entered = (40.0f64 / 4.0).floor() as usize + 1;
        eprintln!(
            "inflow: {} arrived of at most {entered} entered, up to {} running",
            all.arrived, all.vehicles_max
        );
        assert!(all.arrived >= 1 && all.arrived <= entered, "{all:?}");
        assert!(all.vehicles_max > sc.vehicles() + 1, "{all:?}");
        assert_eq!(all.collisions, 0);
        assert_eq!(all.waiting_at_end, 0, "{all:?}");
        // Throughput is the arrivals over the measured time; a vehicle needs at least the
        // ramp and h1 (about 808 m, sumolib) at the speed limit raised by SUMO's largest speed
        // factor (1.2) to cross them, and it entered after t = 0.
        let driven = {
            let ramp = sumolib_length_on(&net, &["ramp", "h1"], &[0, 0], false);
            ramp / (30.0 * 1.2)
        };
        assert!(
            (all.throughput_per_hour - all.arrived as f64 / all.measured_s * 3600.0).abs() < 1e-9
        );
        let tt = all.mean_travel_time_s.expect("vehicles arrived");
        eprintln!("inflow: mean travel time {tt:.2} s, at least {driven:.2} s");
        assert!(tt >= driven && tt <= 40.0, "{tt} s");
        // Close to the bound of one lane at 30 m/s (2880 an hour) SUMO still inserts every
        // vehicle when it is due on this free ramp: those that entered are all that were due
        // (the platoon and the leader included), and none waits.
        let busy = scenario(
            &dir,
            &inflow(serde_json::json!({"vehs_per_hour": 2850})).to_string(),
        )
        .unwrap();
        let mut o = opts(&dir);
        o.work_dir = dir.join("busy");
        let run = run_scenario(&busy, &o).unwrap();
        let all = all_vehicles(&run, &busy);
        eprintln!("busy inflow: {all:?}");
        let due = (40.0f64 * 2850.0 / 3600.0).ceil() as usize;
        assert_eq!(
            all.inserted + all.waiting_at_end,
            due + busy.vehicles() + 1,
            "{all:?}"
        );
        assert_eq!(all.waiting_at_end, 0, "{all:?}");
        // Two inflows on the ramp at once share its capacity.
        let mut two = inflow(serde_json::json!({"vehs_per_hour": 1500}));
        let second = two["sumo"]["inflows"][0].clone();
        two["sumo"]["inflows"].as_array_mut().unwrap().push(second);
        let two = scenario(&dir, &two.to_string()).unwrap();
        let mut o = opts(&dir);
        o.work_dir = dir.join("refused-two");
        let e = run_scenario(&two, &o).unwrap_err().to_string();
        assert!(e.starts_with("sumo.inflows[0].vehs_per_hour = 1500: above what edge `ramp` can take in (with the other inflows entering there at the same time, 3000)"), "{e}");
        // Errors, before SUMO starts.
        let refused = |extra: serde_json::Value| {
            let sc = scenario(&dir, &inflow(extra).to_string()).unwrap();
            let mut o = opts(&dir);
            o.work_dir = dir.join("refused");
            let e = run_scenario(&sc, &o).unwrap_err().to_string();
            assert!(!dir.join("refused/sumo.log").exists(), "{e}");
            e
        };
        let e = refused(serde_json::json!({"from": "rmap"}));
        assert!(
            e.starts_with("sumo.inflows[0].from = `rmap`:")
                && e.contains("has no normal edge of that id; nearest ids: `ramp`"),
            "{e}"
        );
        let e = refused(serde_json::json!({"to": "h0"}));
        assert!(
            e.starts_with("sumo.inflows[0].to = `h0`: no route along the connections of")
                && e.ends_with("leads from `ramp` to it (checked before starting SUMO)"),
            "{e}"
        );
        let e = refused(serde_json::json!({"depart_lane": 1}));
        assert_eq!(e, "sumo.inflows[0].depart_lane = 1: edge `ramp` has 1 lane(s), indices 0..=0 (checked before starting SUMO)");
        let e = refused(serde_json::json!({"vehs_per_hour": 3000}));
        assert!(e.starts_with("sumo.inflows[0].vehs_per_hour = 3000: above what edge `ramp` can take in: at most about 2880 vehicles per hour on 1 lane(s) departing at 30.0 m/s"), "{e}");
        let e = refused(serde_json::json!({"begin_s": 40}));
        assert!(
            e.starts_with("sumo.inflows[0].begin_s = 40: the run ends at horizon_s = 40 s"),
            "{e}"
        );
        let e = scenario(
            &dir,
            &inflow(serde_json::json!({"vehs_per_hour": -5})).to_string(),
        )
        .unwrap_err();
        assert!(
            e.starts_with("sumo.inflows[0].vehs_per_hour = -5: must be a number > 0"),
            "{e}"
        );
    }

    /// An inflow's controlled vehicles enter among its humans, are driven by their law from
    /// their first step to their last and leave at the end of their route. Checked against
    /// SUMO's own floating-car data: the vehicles of the law's type that SUMO inserted are
    /// the ones the record says entered, those gone before the end left, their travel times
    /// are SUMO's to the step; a `constant-speed-25` vehicle, which SUMO's driver would take to
    /// the 30 m/s limit, settles at 25 m/s; one told 40 m/s keeps to the lane's 30 m/s.
    /// Errors name the field before SUMO starts.
    /// The table's stochastic human drives an inflow's vehicles: collision-free, the same seed
    /// gives the same run, and the noise is what moves them (without it the speeds differ).
    #[test]
    fn an_inflows_vehicles_can_be_syncroads_stochastic_humans() {
        let dir = work("inflow-noisy");
        on_ramp(&dir);
        let road =
            serde_json::json!({"type": "route", "edges": ["h0", "h1", "h2"], "lane": "follow"});
        let with_noise = |noise: f64| {
            let inflows = serde_json::json!([
                {"from": "ramp", "to": "h1", "vehs_per_hour": 600,
                 "controlled": {"law": "noisy-idm",
                                "params": {"noise": noise, "accel": 1.3, "tau": 0.8},
                                "share": 1}}
            ]);
            let mut file = platoon_on(
                road.clone(),
                serde_json::json!({"net": "out.net.xml", "fcd": true, "inflows": inflows}),
            );
            file["horizon_s"] = 40.0.into();
            scenario(&dir, &file.to_string()).unwrap()
        };
        let speeds = |sc: &syncroad_control::Scenario, run_dir: &str| {
            let mut o = opts(&dir);
            o.work_dir = dir.join(run_dir);
            let run = run_scenario(sc, &o).unwrap();
            let fin = run.outcome().expect("horizon reached");
            assert_eq!(fin.totals.collision_steps, 0);
            let g = run.output(sc).sumo.unwrap().guests.unwrap();
            assert!(g.entered >= 4, "{g:?}");
            let fcd = std::fs::read_to_string(dir.join(run_dir).join("fcd.xml")).unwrap();
            let doc = roxmltree::Document::parse(&fcd).unwrap();
            let mut by: std::collections::BTreeMap<String, Vec<f64>> = Default::default();
            for v in doc.descendants().filter(|n| n.has_tag_name("vehicle")) {
                if v.attribute("type") == Some("syncroad_guest0") {
                    by.entry(v.attribute("id").unwrap().to_string())
                        .or_default()
                        .push(v.attribute("speed").unwrap().parse().unwrap());
                }
            }
            by
        };
        let noisy = with_noise(0.3);
        let a = speeds(&noisy, "run-a");
        assert_eq!(a, speeds(&noisy, "run-b"), "the same seed, the same run");
        let quiet = speeds(&with_noise(0.0), "run-quiet");
        let (x, y) = (a.values().next().unwrap(), quiet.values().next().unwrap());
        let apart = x
            .iter()
            .zip(y)
            .map(|(p, q)| (p - q).abs())
            .fold(0.0, f64::max);
        assert!(apart > 0.05, "the noise moved nothing: {apart}");
    }

    #[test]
    fn an_inflows_controlled_vehicles_enter_are_driven_and_leave() {
        let dir = work("inflow-controlled");
        on_ramp(&dir);
        let road =
            serde_json::json!({"type": "route", "edges": ["h0", "h1", "h2"], "lane": "follow"});
        let with = |inflows: serde_json::Value| {
            let mut file = platoon_on(
                road.clone(),
                serde_json::json!({"net": "out.net.xml", "fcd": true, "inflows": inflows}),
            );
            file["horizon_s"] = 40.0.into();
            file
        };
        let inflows = serde_json::json!([
            {"from": "ramp", "to": "h1", "vehs_per_hour": 900,
             "controlled": {"law": "constant-speed-25", "share": 0.5, "at_s": [2.5]}},
            {"from": "ramp", "to": "h1", "vehs_per_hour": 300, "begin_s": 20,
             "controlled": {"law": "constant-speed", "params": {"target_speed_mps": 40}, "at_s": [1]}}
        ]);
        let sc = scenario(&dir, &with(inflows.clone()).to_string()).unwrap();
        let run = run_scenario(&sc, &opts(&dir)).unwrap();
        let fin = run.outcome().expect("horizon reached");
        let g = run
            .output(&sc)
            .sumo
            .unwrap()
            .guests
            .expect("controlled inflows");
        eprintln!("controlled inflow vehicles: {g:?}");
        assert_eq!(
            g.laws,
            ["inflow0: constant-speed-25", "inflow1: constant-speed-40"]
        );
        assert_eq!(fin.totals.collision_steps, 0);
        let flows = std::fs::read_to_string(dir.join("run/inflows.rou.xml")).unwrap();
        assert!(flows.contains(r#"<vTypeDistribution id="inflow0_types" vTypes="DEFAULT_VEHTYPE syncroad_guest0" probabilities="0.5 0.5"/>"#), "{flows}");
        assert!(
            flows.contains(r#"<trip id="inflow1.at0" type="syncroad_guest1" depart="1""#),
            "{flows}"
        );
        // SUMO's record of every vehicle of the law's types, step by step.
        let fcd = std::fs::read_to_string(dir.join("run/fcd.xml")).unwrap();
        let doc = roxmltree::Document::parse(&fcd).unwrap();
        let mut seen: std::collections::BTreeMap<String, (String, Vec<(f64, f64)>)> =
            std::collections::BTreeMap::new();
        let mut last_t = 0.0;
        for step in doc.descendants().filter(|n| n.has_tag_name("timestep")) {
            let t: f64 = step.attribute("time").unwrap().parse().unwrap();
            last_t = t;
            for v in step.children().filter(|n| n.has_tag_name("vehicle")) {
                let ty = v.attribute("type").unwrap();
                if ty.starts_with("syncroad_guest") {
                    let speed: f64 = v.attribute("speed").unwrap().parse().unwrap();
                    seen.entry(v.attribute("id").unwrap().to_string())
                        .or_insert_with(|| (ty.to_string(), Vec::new()))
                        .1
                        .push((t, speed));
                }
            }
        }
        assert_eq!(g.entered, seen.len(), "{seen:?}");
        assert!(seen.contains_key("inflow0.at0") && seen.contains_key("inflow1.at0"));
        // Half of the first inflow's regular vehicles (one every 4 s) are drawn as the law's.
        let drawn = seen.keys().filter(|id| !id.contains(".at")).count();
        assert!((2..=9).contains(&drawn), "{drawn} of 10 drawn");
        let left: Vec<&(String, Vec<(f64, f64)>)> = seen
            .values()
            .filter(|(_, r)| r.last().unwrap().0 < last_t)
            .collect();
        assert_eq!(g.left, left.len());
        assert_eq!(g.present_at_end, seen.len() - left.len());
        assert!(g.left >= 2, "{g:?}");
        // A vehicle leaves during the step after its last record.
        let dt = sc.step_s();
        let mean = left
            .iter()
            .map(|(_, r)| r.last().unwrap().0 + dt - r[0].0)
            .sum::<f64>()
            / left.len() as f64;
        assert_relative_eq!(g.mean_travel_time_s.unwrap(), mean, max_relative = 1e-9);
        for (id, (ty, r)) in &seen {
            let top = r.iter().map(|x| x.1).fold(0.0, f64::max);
            // SUMO writes speeds to 0.01 m/s.
            assert!(top <= 30.0 + 0.005, "{id}: {top} m/s");
            // Down to 25 m/s within the vehicle's deceleration, and never above it again
            // (slower where SUMO's safe speed holds it back behind a slower vehicle).
            if ty == "syncroad_guest0" && r.len() > 100 {
                let at = r.iter().position(|x| (x.1 - 25.0).abs() <= 0.005);
                let at = at.unwrap_or_else(|| panic!("{id} never at 25 m/s: {r:?}"));
                assert!(r[at..].iter().all(|x| x.1 <= 25.005), "{id}: {r:?}");
            }
        }
        assert!(g.speed_limited_commands > 0, "{g:?}");
        // Errors, before SUMO starts.
        let refused = |controlled: serde_json::Value| {
            let f = serde_json::json!([{"from": "ramp", "to": "h1", "vehs_per_hour": 900,
                                        "controlled": controlled}]);
            scenario(&dir, &with(f).to_string()).unwrap_err()
        };
        let e = refused(serde_json::json!({"law": "bcm", "share": 0.1}));
        assert!(
            e.starts_with(
                "sumo.inflows[0].controlled.law = bcm: this law reads the vehicle behind"
            ),
            "{e}"
        );
        let e = refused(serde_json::json!({"law": "law", "share": 0.1}));
        assert!(
            e.starts_with(
                "sumo.inflows[0].controlled.law = law: the scenario's own law drives its fixed set"
            ),
            "{e}"
        );
        let e = refused(serde_json::json!({"law": "follower-stoper-20", "share": 0.1}));
        assert!(e.starts_with("sumo.inflows[0].controlled.law = follower-stoper-20: unknown controller; use follower-stopper-X"), "{e}");
        let e = refused(serde_json::json!({"law": "pi-saturation", "share": 1.5}));
        assert_eq!(e, "sumo.inflows[0].controlled.share = 1.5: must be a share in [0, 1] of the inflow's vehicles");
        let e = refused(serde_json::json!({"law": "pi-saturation", "at_s": [-1]}));
        assert_eq!(
            e,
            "sumo.inflows[0].controlled.at_s[0] = -1: must be a departure time ≥ 0 s"
        );
        let e = refused(
            serde_json::json!({"law": "constant-speed", "params": {"speed": 3}, "share": 0.1}),
        );
        assert!(
            e.starts_with("sumo.inflows[0].controlled.law = constant-speed:"),
            "{e}"
        );
        let late = serde_json::json!([{"from": "ramp", "to": "h1", "vehs_per_hour": 900,
                                       "controlled": {"law": "pi-saturation", "at_s": [5, 40]}}]);
        let sc = scenario(&dir, &with(late).to_string()).unwrap();
        let mut o = opts(&dir);
        o.work_dir = dir.join("refused");
        let e = run_scenario(&sc, &o).unwrap_err().to_string();
        assert!(!dir.join("refused/sumo.log").exists(), "{e}");
        assert!(
            e.starts_with(
                "sumo.inflows[0].controlled.at_s[1] = 40: the run ends at horizon_s = 40 s"
            ),
            "{e}"
        );
    }

    /// The inflows' controlled vehicles read and commanded through libsumo's C++ functions in
    /// one batch per step (the default) and one Python call per vehicle and value
    /// (`ReadMode::Getters`) drive the same run: the same vehicles at the same speeds every
    /// step in SUMO's floating-car data, the same record of them (commands, overrides, mean
    /// speed, travel times), the same platoon. The FollowerStopper reads the vehicle ahead
    /// and its speed; SUMO holding back some of its commands shows it met leaders. (The
    /// direct calls need all their functions: `direct_calls` says the inflows' went so too.)
    #[test]
    fn an_inflows_vehicles_drive_alike_through_direct_calls_and_through_python() {
        let dir = work("inflow-direct");
        on_ramp(&dir);
        let road =
            serde_json::json!({"type": "route", "edges": ["h0", "h1", "h2"], "lane": "follow"});
        let inflows = serde_json::json!([
            {"from": "ramp", "to": "h1", "vehs_per_hour": 1200,
             "controlled": {"law": "follower-stopper-25", "share": 0.5}}
        ]);
        let mut file = platoon_on(
            road,
            serde_json::json!({"net": "out.net.xml", "fcd": true, "inflows": inflows}),
        );
        file["horizon_s"] = 40.0.into();
        let sc = scenario(&dir, &file.to_string()).unwrap();
        let drive = |mode: syncroad_sumo::ReadMode, run_dir: &str| {
            let mut o = opts(&dir);
            o.work_dir = dir.join(run_dir);
            o.read = mode;
            let run = run_scenario(&sc, &o).unwrap();
            let fin = run.outcome().expect("horizon reached");
            let direct = fin.totals.direct_calls;
            let guests = run.output(&sc).sumo.unwrap().guests.unwrap();
            let fcd = std::fs::read_to_string(dir.join(run_dir).join("fcd.xml")).unwrap();
            let doc = roxmltree::Document::parse(&fcd).unwrap();
            let speeds: Vec<(String, String, String)> = doc
                .descendants()
                .filter(|n| n.has_tag_name("vehicle"))
                .map(|v| {
                    let a = |k: &str| v.attribute(k).unwrap().to_string();
                    (a("id"), a("speed"), a("pos"))
                })
                .collect();
            (direct, guests, speeds, run.worker.rows.speeds_mps.clone())
        };
        let (direct, g, fcd, rows) = drive(syncroad_sumo::ReadMode::Direct, "direct");
        let (python, g_python, fcd_python, rows_python) =
            drive(syncroad_sumo::ReadMode::Getters, "python");
        assert!(
            direct && !python,
            "the pinned libsumo exports the functions"
        );
        eprintln!("inflow vehicles, direct calls: {g:?}");
        assert!(g.entered >= 3 && g.commands > 500, "{g:?}");
        assert!(g.overridden_commands > 0, "no leader held one back: {g:?}");
        assert_eq!(g, g_python);
        assert_eq!(fcd, fcd_python);
        assert_eq!(rows, rows_python);
    }

    /// Flow's merge with one's own controller: a highway with an on-ramp and no vehicles of
    /// syncroad's own, a share of the highway's inflow driven by a Python class (one instance
    /// per vehicle, from its entry to its exit). The guide's Python FollowerStopper,
    /// written apart from the built-in law, drives them as `follower-stopper-20` does: the
    /// same vehicles at the same speeds in SUMO's own floating-car data, to rounding. A class
    /// that raises ends the run with its rows kept and its traceback; bad input names the
    /// field before SUMO starts.
    #[test]
    fn an_inflows_vehicles_can_be_driven_by_ones_own_python_controller() {
        let dir = work("inflow-python");
        on_ramp(&dir);
        let controllers = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/controllers");
        let fs = controllers
            .join("follower_stopper.py")
            .display()
            .to_string();
        let file = |controlled: serde_json::Value| {
            serde_json::json!({"name": "merge", "backend": "sumo", "seed": 3, "step_s": 0.1,
                "horizon_s": 60, "vehicles": 0,
                "road": {"type": "route", "edges": ["h0", "h1", "h2"], "lane": "follow"},
                "sumo": {"net": "out.net.xml", "fcd": true, "inflows": [
                    {"from": "h0", "to": "h2", "vehs_per_hour": 1800, "controlled": controlled},
                    {"from": "ramp", "to": "h2", "vehs_per_hour": 600}]}})
            .to_string()
        };
        let fcd_speeds = |run_dir: &str| {
            let fcd = std::fs::read_to_string(dir.join(run_dir).join("fcd.xml")).unwrap();
            let doc = roxmltree::Document::parse(&fcd).unwrap();
            let mut by: std::collections::BTreeMap<String, Vec<f64>> = Default::default();
            for v in doc.descendants().filter(|n| n.has_tag_name("vehicle")) {
                if v.attribute("type") == Some("syncroad_guest0") {
                    by.entry(v.attribute("id").unwrap().to_string())
                        .or_default()
                        .push(v.attribute("speed").unwrap().parse().unwrap());
                }
            }
            by
        };
        let run_in = |sc: &Scenario, run_dir: &str| {
            let mut o = opts(&dir);
            o.work_dir = dir.join(run_dir);
            run_scenario(sc, &o).unwrap()
        };
        let built_in = scenario(
            &dir,
            &file(serde_json::json!({"law": "follower-stopper-20", "share": 0.3})),
        )
        .unwrap();
        let python = scenario(
            &dir,
            &file(
                serde_json::json!({"python": format!("{fs}:FollowerStopper"),
                                     "params": {"desired_speed_mps": 20}, "share": 0.3}),
            ),
        )
        .unwrap();
        assert_ne!(built_in.hash_hex(), python.hash_hex());
        let a = run_in(&built_in, "built-in");
        a.outcome().expect("horizon reached");
        let b = run_in(&python, "python");
        b.outcome().expect("horizon reached");
        let g = b.output(&python).sumo.unwrap().guests.unwrap();
        assert_eq!(g.laws, ["inflow0: python:FollowerStopper"]);
        assert!(g.entered >= 5, "{g:?}");
        let (x, y) = (fcd_speeds("built-in"), fcd_speeds("python"));
        assert_eq!(x.keys().collect::<Vec<_>>(), y.keys().collect::<Vec<_>>());
        assert!(x.len() >= 5, "{x:?}");
        let worst = x
            .values()
            .zip(y.values())
            .flat_map(|(p, q)| {
                assert_eq!(p.len(), q.len());
                p.iter().zip(q).map(|(a, b)| (a - b).abs())
            })
            .fold(0.0, f64::max);
        assert!(
            worst < 1e-6,
            "Python and built-in FollowerStopper differ by {worst} m/s"
        );
        // A class that raises on its tenth step ends the run there, naming it.
        std::fs::write(
            dir.join("raises.py"),
            "class Raises:\n    def __init__(self):\n        self.n = 0\n    def step(self, obs):\n        self.n += 1\n        if self.n == 10:\n            raise RuntimeError('planted failure')\n        return obs.speed_mps\n",
        )
        .unwrap();
        let raises = scenario(
            &dir,
            &file(serde_json::json!({"python": "raises.py:Raises", "share": 1})),
        )
        .unwrap();
        let run = run_in(&raises, "raises");
        let stop = run.outcome().expect_err("stopped by the controller");
        let text = format!("{stop:?}");
        assert!(text.contains("planted failure"), "{text}");
        // Bad input, before SUMO starts, naming the field.
        for (controlled, expected) in [
            (
                serde_json::json!({"python": "missing.py:X", "share": 0.3}),
                "sumo.inflows[0].controlled.python = missing.py:X",
            ),
            (
                serde_json::json!({"python": format!("{fs}:FollowerStopper"), "law": "lacc"}),
                "sumo.inflows[0].controlled = law = lacc, python = ",
            ),
            (
                serde_json::json!({"share": 0.3}),
                "sumo.inflows[0].controlled = {}: name who drives them",
            ),
        ] {
            let e = scenario(&dir, &file(controlled)).unwrap_err();
            assert!(e.starts_with(expected), "{e}");
        }
    }

    /// An open road of inflows only (`"vehicles": 0`, no model): SUMO runs the inflow, the
    /// law drives its controlled share, SUMO's summary counts every vehicle, and the verdict
    /// says why there is none; a model beside no vehicles, and no vehicles without an inflow,
    /// are refused naming the field.
    #[test]
    fn an_open_road_of_inflows_only_runs_without_vehicles_of_its_own() {
        let dir = work("inflows-only");
        on_ramp(&dir);
        let file = |extra: &str| {
            format!(
                r#"{{"name": "open", "backend": "sumo", "seed": 3, "step_s": 0.1, "horizon_s": 60,
                    "vehicles": 0, {extra}
                    "road": {{"type": "route", "edges": ["h0", "h1", "h2"], "lane": "follow"}},
                    "sumo": {{"net": "out.net.xml", "inflows": [
                        {{"from": "h0", "to": "h2", "vehs_per_hour": 1800,
                          "controlled": {{"law": "follower-stopper-20", "share": 0.3}}}},
                        {{"from": "ramp", "to": "h2", "vehs_per_hour": 600}}]}}}}"#
            )
        };
        let sc = scenario(&dir, &file("")).unwrap();
        assert_eq!(sc.vehicles(), 0);
        let run = run_scenario(&sc, &opts(&dir)).unwrap();
        run.outcome().expect("horizon reached");
        let out = run.output(&sc);
        assert_eq!(out.trajectory.n, 0);
        let facts = out.sumo.clone().unwrap();
        let all = facts.all_vehicles.clone().expect("every vehicle");
        let g = facts.guests.clone().expect("controlled inflow");
        eprintln!("open road: {all:?}\n{g:?}");
        // 60 s of 1800 + 600 an hour, regular (one every 2 s and every 6 s from t = 0 on):
        // 30 + 10 due.
        assert_eq!(all.inserted + all.waiting_at_end, 30 + 10, "{all:?}");
        assert!(g.entered >= 3 && g.entered < 30, "{g:?}");
        assert_eq!(all.collisions, 0);
        let outcome = syncroad_control::outcome::evaluate(
            &sc,
            &out,
            syncroad_control::outcome::EvalOptions::of(&sc),
        );
        assert_eq!(
            outcome.sync.verdict,
            syncroad_control::Verdict::Inconclusive
        );
        assert_eq!(
            outcome.sync.verdict_reason.as_deref(),
            Some(syncroad_control::outcome::NO_FIXED_SET)
        );
        assert!(!outcome.theory.certified);
        let e = scenario(
            &dir,
            &file(r#""model": {"type": "delayed_driver", "delay_s": 0.5, "graph": {"type": "unidirectional_ring", "gain": 1}},"#),
        )
        .unwrap_err();
        assert!(
            e.starts_with("model = given: the scenario has no vehicles of its own"),
            "{e}"
        );
        for (extra, field) in [
            (r#""controller": {"python": "c.py:C"},"#, "controller"),
            (r#""mixed": {"penetration": 0.5},"#, "mixed"),
        ] {
            let e = scenario(&dir, &file(extra)).unwrap_err();
            assert!(
                e.starts_with(&format!(
                    "{field} = given: the scenario has no vehicles of its own"
                )),
                "{e}"
            );
        }
        let e = scenario(
            &dir,
            &file("").replace(r#""inflows": ["#, r#""inflows_": ["#),
        )
        .unwrap_err();
        assert!(e.contains("inflows_"), "{e}");
        let none = file("").replace(r#""vehicles": 0,"#, r#""vehicles": 2,"#);
        let e = scenario(&dir, &none).unwrap_err();
        assert!(
            e.starts_with("model = missing: give the law of the scenario's vehicles"),
            "{e}"
        );
    }

    /// A lane drop built by netconvert: three lanes into two, so only lanes 1 and 2 of `up`
    /// lead on. The entry's capacity counts the lanes an inflow departs on: SUMO's `"best"`
    /// (the default) takes the two that lead on, `"free"` all three, an index one, and two
    /// inflows on lanes of their own share nothing. Checked before SUMO starts.
    #[test]
    fn an_inflows_capacity_counts_the_lanes_it_departs_on() {
        let dir = work("lane-drop");
        std::fs::write(
            dir.join("drop.nod.xml"),
            "<nodes>\n  <node id=\"a\" x=\"0\" y=\"0\"/>\n  <node id=\"d\" x=\"1000\" y=\"0\"/>\n  <node id=\"b\" x=\"1500\" y=\"0\"/>\n</nodes>\n",
        )
        .unwrap();
        std::fs::write(
            dir.join("drop.edg.xml"),
            "<edges>\n  <edge id=\"up\" from=\"a\" to=\"d\" numLanes=\"3\" speed=\"30\"/>\n  <edge id=\"narrow\" from=\"d\" to=\"b\" numLanes=\"2\" speed=\"30\"/>\n</edges>\n",
        )
        .unwrap();
        let net = netconvert(
            &dir,
            &[
                "--node-files",
                "drop.nod.xml",
                "--edge-files",
                "drop.edg.xml",
            ],
        );
        let text = std::fs::read_to_string(&net).unwrap();
        assert!(!text.contains(r#"<connection from="up" to="narrow" fromLane="0""#));
        // 3600·30 / (5 + 2.5 + 30) per lane.
        let lane = 2880.0;
        let attempt = |inflows: serde_json::Value| -> Result<(), String> {
            let file = serde_json::json!({
                "name": "drop", "backend": "sumo", "seed": 1, "step_s": 0.1, "horizon_s": 5,
                "vehicles": 0,
                "road": {"type": "route", "edges": ["up", "narrow"], "lane": "follow"},
                "sumo": {"net": "out.net.xml", "inflows": inflows}});
            let sc = scenario(&dir, &file.to_string())?;
            let mut o = opts(&dir);
            o.work_dir = dir.join("run");
            run_scenario(&sc, &o).map(|_| ()).map_err(|e| e.to_string())
        };
        let one = |vph: f64, lane: serde_json::Value| {
            let mut f = serde_json::json!({"from": "up", "to": "narrow", "vehs_per_hour": vph});
            if !lane.is_null() {
                f["depart_lane"] = lane;
            }
            serde_json::json!([f])
        };
        attempt(one(2.0 * lane - 10.0, serde_json::Value::Null)).unwrap();
        let e = attempt(one(2.0 * lane + 10.0, serde_json::Value::Null)).unwrap_err();
        assert!(
            e.contains("at most about 5760 vehicles per hour on 2 lane(s) departing at 30.0 m/s"),
            "{e}"
        );
        attempt(one(3.0 * lane - 10.0, "free".into())).unwrap();
        let e = attempt(one(3.0 * lane + 10.0, "free".into())).unwrap_err();
        assert!(e.contains("on 3 lane(s)"), "{e}");
        let e = attempt(one(lane + 10.0, 0.into())).unwrap_err();
        assert!(
            e.contains("at most about 2880 vehicles per hour on 1 lane(s)"),
            "{e}"
        );
        let mut two = one(lane - 10.0, 0.into());
        two.as_array_mut()
            .unwrap()
            .push(one(lane - 10.0, 2.into())[0].clone());
        attempt(two).unwrap();
    }

    /// `sumo.vclass` takes SUMO's classes: sumolib's list of every class name it reads, less
    /// the names SUMO keeps only as deprecated aliases.
    #[test]
    fn the_vehicle_classes_are_sumos_own() {
        let out = Command::new(venv().join("bin/python"))
            .args([
                "-c",
                "import sumolib.net.lane as l; print('\\n'.join(sorted(l.SUMO_VEHICLE_CLASSES)))",
            ])
            .output()
            .expect("python runs");
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let text = String::from_utf8(out.stdout).unwrap();
        let sumolib: std::collections::BTreeSet<&str> = text.lines().collect();
        let ours: std::collections::BTreeSet<&str> = syncroad_control::scenario::VEHICLE_CLASSES
            .into_iter()
            .collect();
        assert_eq!(
            ours.len(),
            syncroad_control::scenario::VEHICLE_CLASSES.len()
        );
        let deprecated: std::collections::BTreeSet<&str> = [
            "public_emergency",
            "public_authority",
            "public_army",
            "public_transport",
            "transport",
            "lightrail",
            "cityrail",
            "rail_slow",
            "rail_fast",
        ]
        .into_iter()
        .collect();
        assert_eq!(
            sumolib
                .difference(&ours)
                .copied()
                .collect::<std::collections::BTreeSet<_>>(),
            deprecated
        );
        assert!(ours.is_subset(&sumolib), "{:?}", ours.difference(&sumolib));
    }

    /// A lane that admits buses only: passenger cars are refused before SUMO starts, buses
    /// (`sumo.vclass`) drive it, their vType says so, and SUMO gives the native simulator's
    /// speeds across it; a class SUMO does not have is named with the ones it has.
    #[test]
    fn vehicles_of_the_lanes_class_drive_a_bus_lane() {
        let dir = work("bus-lane");
        highway(&dir, true, false);
        let road =
            serde_json::json!({"type": "route", "edges": ["h0", "h1", "h2", "h3"], "lane": 0});
        let cars = platoon_on(road.clone(), serde_json::json!({"net": "out.net.xml"}));
        let e = scenario(&dir, &cars.to_string()).unwrap_err();
        assert!(
            e.contains("is closed to class passenger (allow=\"bus\")"),
            "{e}"
        );
        let buses = platoon_on(
            road.clone(),
            serde_json::json!({"net": "out.net.xml", "vclass": "bus"}),
        );
        let sc = scenario(&dir, &buses.to_string()).unwrap();
        let run = run_scenario(&sc, &opts(&dir)).unwrap();
        let fin = run.outcome().expect("horizon reached");
        assert_eq!(fin.totals.collision_steps, 0);
        let routes = std::fs::read_to_string(dir.join("run/routes.rou.xml")).unwrap();
        assert!(routes.contains(r#"vClass="bus""#), "{routes}");
        let native = simulate(&sc, NativeOptions::default()).trajectory;
        let worst = worst_speed_difference(&native.speeds_mps, &run.trajectory(&sc).speeds_mps);
        assert!(worst < 1e-9, "largest speed difference {worst} m/s");
        // Passenger cars following the connections avoid the bus lane: lane 0 of h0 leads
        // only onto it, so the search starts again from lane 1.
        let follow = serde_json::json!({"type": "route", "edges": ["h0", "h1", "h2", "h3"], "lane": "follow"});
        let sc = scenario(
            &dir,
            &platoon_on(follow, serde_json::json!({"net": "out.net.xml"})).to_string(),
        )
        .unwrap();
        assert_eq!(sc.measured_road().unwrap().lanes, [1, 1, 1, 1]);
        let typo = platoon_on(
            road,
            serde_json::json!({"net": "out.net.xml", "vclass": "buss"}),
        );
        let e = scenario(&dir, &typo.to_string()).unwrap_err();
        assert!(
            e.starts_with(
                "sumo.vclass = \"buss\": not one of SUMO's vehicle classes: passenger, private,"
            ),
            "{e}"
        );
    }
}

/// Every road error is found before SUMO starts and names the field.
mod errors {
    use super::*;

    /// A ring scenario on a network of several lanes points to the road types that drive one
    /// (it once said "single-lane roads only", as if syncroad had none).
    #[test]
    fn a_ring_on_a_two_lane_network_points_to_a_loop() {
        let dir = work("errors-two-lane-ring");
        let net = two_lane_loop(&dir);
        let json = format!(
            r#"{{"name": "two-lane", "backend": "sumo", "seed": 1, "step_s": 0.1, "horizon_s": 10,
                "vehicles": 4, "road": {{"type": "ring", "length_m": 600}},
                "model": {{"type": "delayed_driver",
                          "graph": {{"type": "unidirectional_ring", "gain": 0.5}}, "delay_s": 0.5}},
                "sumo": {{"net": "{}"}}}}"#,
            net.display()
        );
        let sc = Scenario::from_json(&json).unwrap();
        let e = load_road(&sc).unwrap_err().to_string();
        assert!(e.contains("edge `e0` has 2 lanes"), "{e}");
        assert!(
            e.contains("give road.type \"loop\" (a closed cycle) or \"route\" (an open road)"),
            "{e}"
        );
    }

    fn err(dir: &Path, road: &str, vehicles: usize) -> String {
        scenario(dir, &loop_json(road, vehicles, 10.0, "")).unwrap_err()
    }

    #[test]
    fn loop_errors_name_the_field_and_what_would_be_valid() {
        let dir = work("errors-loop");
        let net = two_lane_loop(&dir);
        let net = net.display();
        let e = err(
            &dir,
            r#"{"type": "loop", "edges": ["e0", "e33"], "lane": 0}"#,
            4,
        );
        assert_eq!(
            e,
            format!("road.edges[1] = `e33`: {net} has no normal edge of that id; nearest ids: `e3`, `e0`, `e1`")
        );
        let e = err(
            &dir,
            r#"{"type": "loop", "edges": ["e0", "e1"], "lane": 2}"#,
            4,
        );
        assert_eq!(
            e,
            "road.lane = 2: edge `e0` (road.edges[0]) has 2 lane(s), indices 0..=1; choose a lane it has"
        );
        let e = err(
            &dir,
            r#"{"type": "loop", "edges": ["e0", "e2", "e3"], "lane": 0}"#,
            4,
        );
        assert_eq!(
            e,
            format!("road.edges[0] `e0` → road.edges[1] `e2`: {net} connects no lane 0 of `e0` to lane 0 of `e2`; `e0` does not lead to `e2` at all; it leads to `out`, `e1`")
        );
        let seven =
            r#"{"type": "loop", "edges": ["e0", "e1", "e2", "e3", "e4", "e5", "e6"], "lane": 1}"#;
        let e = err(&dir, seven, 4);
        assert_eq!(
            e,
            format!("road.edges: the loop does not close: road.edges[6] `e6` has no connection back to road.edges[0] `e0` on lane 1 in {net}; `e6` does not lead to `e0` at all; it leads to `e7` (a loop lists its cycle in driving order; for an open road use road.type = \"route\")")
        );
        let e = err(
            &dir,
            r#"{"type": "loop", "edges": ["e0", "e1", "e0"], "lane": 0}"#,
            4,
        );
        assert_eq!(
            e,
            "road.edges[2] = `e0` repeats road.edges[0]; a road passes each edge once"
        );
        let e = err(&dir, r#"{"type": "loop", "through": "out", "lane": 0}"#, 4);
        assert_eq!(
            e,
            format!("road.through = `out`: no cycle on lane 0 leads back to it through the connections of {net} (0 other edges are reachable from it on that lane, none leads back); give the cycle as road.edges, another edge or another lane")
        );
        let e = err(
            &dir,
            r#"{"type": "loop", "through": "e1", "edges": ["e1"]}"#,
            4,
        );
        assert!(
            e.starts_with("road.through = given with road.edges: give either"),
            "{e}"
        );
        let e = err(&dir, r#"{"type": "loop", "lane": 0}"#, 4);
        assert!(e.starts_with("road.edges = missing: a loop needs"), "{e}");
        let e = err(&dir, r#"{"type": "loop", "edges": [], "lane": 0}"#, 4);
        assert_eq!(e, "road.edges = []: a loop needs at least one edge");
    }

    #[test]
    fn vehicles_that_do_not_fit_on_the_loop_are_refused() {
        let dir = work("errors-fit");
        two_lane_loop(&dir);
        let road = r#"{"type": "loop", "through": "e0", "lane": 1}"#;
        let len = scenario(&dir, &loop_json(road, 4, 10.0, ""))
            .unwrap()
            .ring_length_m()
            .unwrap();
        let too_many = (len / 5.0).floor() as usize + 1;
        let e = err(&dir, road, too_many);
        assert_eq!(
            e,
            format!(
                "vehicles = {too_many}: {too_many} vehicles of {:.2} m in all do not fit on the loop, {len:.3} m long as measured on its network; at most {} fit",
                5.0 * too_many as f64,
                too_many - 1
            )
        );
        // They fit bumper to bumper but not with SUMO's minGap: refused before SUMO starts.
        let sc = scenario(&dir, &loop_json(road, too_many - 1, 10.0, "")).unwrap();
        let e = run_scenario(&sc, &opts(&dir)).unwrap_err().to_string();
        assert!(e.contains("is overfull"), "{e}");
        assert!(!dir.join("run/sumo.log").exists());
        // Gaps that do not add up to the measured length name it.
        let e = scenario(&dir, &loop_json(road, 4, 10.0, r#", "gap_m": 10"#)).unwrap_err();
        assert!(
            e.contains(&format!(
                "must add up to the loop's length measured on its network, {len} m"
            )),
            "{e}"
        );
    }

    #[test]
    fn route_errors_name_the_lanes_that_do_connect_and_the_permissions() {
        let dir = work("errors-route");
        let net = highway(&dir, true, true);
        let net = net.display();
        let route = |lane: usize| {
            format!(r#"{{"type": "route", "edges": ["h0", "h1", "h2", "h3"], "lane": {lane}}}"#)
        };
        let e = err(&dir, &route(2), 4);
        assert_eq!(
            e,
            format!("road.edges[2] `h2` → road.edges[3] `h3`: {net} connects no lane 2 of `h2` to lane 2 of `h3`; its connections to `h3` join lanes 0→0, 1→1, 2→1 (a route may change lanes where the connections do: road.lane = \"follow\", or one lane index per edge)")
        );
        let e = err(&dir, &route(0), 4);
        assert_eq!(
            e,
            format!("road.edges[2]: lane `h2_0` of {net} is closed to class passenger (allow=\"bus\"); syncroad's vehicles are of class passenger (sumo.vclass), so choose another lane (road.lane), edges open to them, or a class the lanes allow (sumo.vclass)")
        );
        assert!(scenario(&dir, &loop_json(&route(1), 4, 10.0, "")).is_ok());
        // A road through a network needs one.
        let no_net = loop_json(&route(1), 4, 10.0, "")
            .replace(r#""sumo": {"net": "out.net.xml"}"#, r#""sumo": {}"#);
        let e = scenario(&dir, &no_net).unwrap_err();
        assert!(
            e.starts_with("sumo.net = missing: road.type = \"route\" runs through a network"),
            "{e}"
        );
    }
}
