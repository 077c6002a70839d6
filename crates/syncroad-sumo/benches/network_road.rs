//! Finding and measuring a loop on a 10 000-edge network (target: under 1 s).
//!
//! The network is made by SUMO's `netgenerate` from the project's virtualenv: a 51 × 51 grid
//! of 100 m blocks, two lanes each way, 10 200 normal edges, every junction with its internal
//! lanes (a 25 MB `.net.xml`). Timed: `read_network_road` for `{"type": "loop", "through": e,
//! "lane": 1}` — reading and parsing the file, the shortest-cycle search over all edges and
//! the measurement of the cycle's lanes — and the same for a 50-edge route across the grid.
//! The grid's shortest cycles are one block; the search's worst case is a cycle through every
//! edge, timed on a single-lane ring of 10 000 edges (10 000 nodes on a 100 km circle, built by
//! `netconvert`), found from one edge (`through`) and given whole (`edges`).
//!
//! Run with `cargo bench -p syncroad-sumo --bench network_road`.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use criterion::{criterion_group, criterion_main, Criterion};
use syncroad_control::scenario::{RoadSpec, RouteLanes, VehicleClass};
use syncroad_sumo::read_network_road;

fn grid() -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("bench-network-road");
    std::fs::create_dir_all(&dir).unwrap();
    let net = dir.join("grid51.net.xml");
    if !net.is_file() {
        let bin = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../.venv/lib/python3.11/site-packages/sumo/bin/netgenerate");
        let st = Command::new(bin)
            .args([
                "--grid",
                "--grid.number",
                "51",
                "--grid.length",
                "100",
                "--default.lanenumber",
                "2",
                "--no-turnarounds",
                "true",
                "--no-warnings",
                "true",
                "-o",
            ])
            .arg(&net)
            .status()
            .expect("netgenerate runs");
        assert!(st.success());
    }
    net
}

/// A single-lane ring of 10 000 edges through 10 000 nodes on a circle of 100 km.
fn big_ring() -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("bench-network-road");
    std::fs::create_dir_all(&dir).unwrap();
    let net = dir.join("ring10000.net.xml");
    if !net.is_file() {
        let n = RING_EDGES;
        let r = 100_000.0 / (2.0 * std::f64::consts::PI);
        let mut nod = String::from("<nodes>\n");
        let mut edg = String::from("<edges>\n");
        for i in 0..n {
            let a = 2.0 * std::f64::consts::PI * i as f64 / n as f64;
            nod += &format!(
                "<node id=\"n{i}\" x=\"{:.3}\" y=\"{:.3}\"/>\n",
                r * a.cos(),
                r * a.sin()
            );
            edg += &format!(
                "<edge id=\"e{i}\" from=\"n{i}\" to=\"n{}\" numLanes=\"1\" speed=\"30\"/>\n",
                (i + 1) % n
            );
        }
        std::fs::write(dir.join("ring.nod.xml"), nod + "</nodes>\n").unwrap();
        std::fs::write(dir.join("ring.edg.xml"), edg + "</edges>\n").unwrap();
        let bin = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../.venv/lib/python3.11/site-packages/sumo/bin/netconvert");
        let st = Command::new(bin)
            .current_dir(&dir)
            .args([
                "--node-files",
                "ring.nod.xml",
                "--edge-files",
                "ring.edg.xml",
            ])
            .args(["--no-turnarounds", "true", "--no-warnings", "true", "-o"])
            .arg(&net)
            .status()
            .expect("netconvert runs");
        assert!(st.success());
    }
    net
}

/// Edges of [`big_ring`].
const RING_EDGES: usize = 10_000;

fn bench(c: &mut Criterion) {
    let ring = big_ring();
    let ring_through = RoadSpec::Loop {
        edges: None,
        through: Some("e0".into()),
        lane: 0,
    };
    let ring_edges = RoadSpec::Loop {
        edges: Some((0..RING_EDGES).map(|i| format!("e{i}")).collect()),
        through: None,
        lane: 0,
    };
    let t = Instant::now();
    let road = read_network_road(&ring, &ring_through, VehicleClass::PASSENGER).unwrap();
    eprintln!(
        "loop through e0 of the 10 000-edge ring: {} edges, {:.2} m, found in {:.3} s (first call)",
        road.normal_edges().len(),
        road.length_m(),
        t.elapsed().as_secs_f64()
    );
    assert_eq!(road.normal_edges().len(), RING_EDGES);
    let net = grid();
    let through = RoadSpec::Loop {
        edges: None,
        through: Some("AZ25BA25".into()),
        lane: 1,
    };
    // The route along row 25, west to east: edges AA25AB25, AB25AC25, ….
    let cols: Vec<String> = (0..51).map(col).collect();
    let route = RoadSpec::Route {
        edges: (0..50)
            .map(|i| format!("{}25{}25", cols[i], cols[i + 1]))
            .collect(),
        lane: RouteLanes::Index(1),
    };
    let t = Instant::now();
    let road = read_network_road(&net, &through, VehicleClass::PASSENGER).unwrap();
    eprintln!(
        "loop through AZ25BA25 on lane 1: {} edges, {:.2} m, found in {:.3} s (first call)",
        road.normal_edges().len(),
        road.length_m(),
        t.elapsed().as_secs_f64()
    );
    let mut g = c.benchmark_group("network_road");
    g.sample_size(10).measurement_time(Duration::from_secs(20));
    g.bench_function("loop_through_10200_edges", |b| {
        b.iter(|| read_network_road(&net, &through, VehicleClass::PASSENGER).unwrap())
    });
    g.bench_function("route_50_edges_of_10200", |b| {
        b.iter(|| read_network_road(&net, &route, VehicleClass::PASSENGER).unwrap())
    });
    g.bench_function("loop_through_ring_of_10000_edges", |b| {
        b.iter(|| read_network_road(&ring, &ring_through, VehicleClass::PASSENGER).unwrap())
    });
    g.bench_function("loop_edges_ring_of_10000_edges", |b| {
        b.iter(|| read_network_road(&ring, &ring_edges, VehicleClass::PASSENGER).unwrap())
    });
    g.finish();
}

/// netgenerate's grid names: two letters per column index (AA, AB, …, AZ, BA, …).
fn col(i: usize) -> String {
    let letter = |k: usize| char::from(b'A' + k as u8);
    format!("{}{}", letter(i / 26), letter(i % 26))
}

criterion_group!(benches, bench);
criterion_main!(benches);
