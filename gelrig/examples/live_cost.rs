//! What the live view costs a dry run (BENCHMARKS.md, "Live view"): the same dry run in
//! virtual time without `--live`, and with it while a client polls the page as the browser
//! does (state every 0.5 s, the latest frame and its marker overlay every second), in
//! alternating pairs; medians of the wall time and their ratio.
//!
//! ```text
//! cargo run --release -p gelrig --example live_cost -- [PAIRS]
//! ```

use std::io::{Read, Write};
use std::net::TcpStream;
use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::{Duration, Instant};

use experiments::load::load;
use rig::ClockMode;
use runner::{Cancel, Launch, run};

fn get(host: &str, path: &str) -> usize {
    let Ok(mut s) = TcpStream::connect(host) else {
        return 0;
    };
    let _ = write!(
        s,
        "GET {path} HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\n\r\n"
    );
    let mut body = Vec::new();
    let _ = s.read_to_end(&mut body);
    body.len()
}

/// One dry run of `file` in virtual time; with `live`, served and polled. Wall seconds and,
/// with `live`, the bytes the client fetched.
fn once(file: &Path, live: bool) -> (f64, u64) {
    let loaded = load(file, None).unwrap_or_else(|d| panic!("{}", d[0]));
    let plan = loaded.plan.clone();
    let out = tempfile::tempdir().expect("tmp");
    let board = live
        .then(|| liveview::Board::new(gelrig::view::live_meta(&loaded, &plan, ClockMode::Virtual)));
    let server = board.as_ref().map(|b| {
        liveview::Server::start(
            "127.0.0.1:0".parse().expect("addr"),
            Arc::new(gelrig::view::LiveRun::new(b.clone())),
        )
        .expect("serve")
    });
    let done = Arc::new(AtomicBool::new(false));
    let fetched = Arc::new(AtomicU64::new(0));
    let client = server.as_ref().map(|s| {
        let host = s
            .url()
            .trim_start_matches("http://")
            .trim_end_matches('/')
            .to_string();
        let (done, fetched) = (done.clone(), fetched.clone());
        std::thread::spawn(move || {
            let mut k = 0u64;
            while !done.load(Ordering::Relaxed) {
                let mut n = get(&host, "/run/live/state.json");
                if k.is_multiple_of(2) {
                    n += get(&host, "/run/live/frame.png");
                    n += get(&host, "/run/live/overlay.json");
                }
                fetched.fetch_add(n as u64, Ordering::Relaxed);
                k += 1;
                std::thread::sleep(Duration::from_millis(500));
            }
        })
    });
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .start_paused(true)
        .build()
        .expect("runtime");
    let started = Instant::now();
    let outcome = rt
        .block_on(run(
            Launch::new(&loaded).out(out.path()).seed(1).live(board),
            Cancel::new(),
        ))
        .expect("run");
    let wall = started.elapsed().as_secs_f64();
    assert_eq!(outcome.status, rundir::write::Status::Completed);
    done.store(true, Ordering::Relaxed);
    if let Some(c) = client {
        let _ = c.join();
    }
    drop(server);
    (wall, fetched.load(Ordering::Relaxed))
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let pairs: usize = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(5);
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../protocols");
    let text = std::fs::read_to_string(root.join("lifting-can.yaml")).expect("protocol");
    let can = root.join(".lifting-can-3.yaml");
    std::fs::write(&can, text.replace("times: 10", "times: 3")).expect("write");
    println!(
        "| dry run (virtual time) | without --live, s | with --live and a page polling, s | ratio | fetched per run |"
    );
    println!("|---|---|---|---|---|");
    for (name, file) in [
        ("box-normal-flat", root.join("box-normal-flat.yaml")),
        ("portable-normal", root.join("portable-normal.yaml")),
        ("lifting-can, 3 trials", can.clone()),
    ] {
        let (mut off, mut on, mut bytes) = (Vec::new(), Vec::new(), 0);
        for _ in 0..pairs {
            off.push(once(&file, false).0);
            let (w, b) = once(&file, true);
            on.push(w);
            bytes = b;
        }
        let (a, b) = (median(off), median(on));
        println!(
            "| {name} | {a:.2} | {b:.2} | {:.3} | {:.1} MB |",
            b / a,
            bytes as f64 / 1e6
        );
    }
    let _ = std::fs::remove_file(&can);
}
