//! The live view and `gelrig view`, driven in a real headless browser (Debian's
//! `chromium`, installed by `.ci/run`): the page's scripts run, fetch the run's state and
//! fill the page, and the test reads the DOM they built.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use crate::support::{gelrig, protocol, shared_dry_run};

/// The browser, or `None` with a visible skip line (a failure when CI requires it).
fn browser() -> Option<&'static str> {
    let found = Command::new("chromium")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    if found {
        return Some("chromium");
    }
    testkit::skip(
        testkit::Need::Browser,
        "the live view in a browser",
        "chromium is not installed (apt install chromium)",
    );
    None
}

/// The DOM after the page's scripts ran for `budget_ms` of the browser's virtual time.
fn dom(browser: &str, url: &str, budget_ms: u32) -> String {
    let profile = tempfile::tempdir().unwrap();
    let out = Command::new(browser)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--no-first-run",
            &format!("--user-data-dir={}", profile.path().display()),
            &format!("--virtual-time-budget={budget_ms}"),
            "--dump-dom",
            url,
        ])
        .stderr(Stdio::null())
        .output()
        .unwrap();
    assert!(out.status.success(), "chromium failed on {url}");
    String::from_utf8_lossy(&out.stdout).into_owned()
}

/// The value of `attr="…"` on the element with `id`.
fn attr(dom: &str, id: &str, attr: &str) -> Option<u64> {
    let at = dom.find(&format!("id=\"{id}\""))?;
    let tag_end = at + dom[at..].find('>')?;
    let start = dom[..tag_end].rfind('<')?;
    let tag = &dom[start..tag_end];
    let key = format!("{attr}=\"");
    let v = &tag[tag.find(&key)? + key.len()..];
    v[..v.find('"')?].parse().ok()
}

/// The first `http://…` in the lines `child`'s `stream` prints, within 60 s.
fn url_from(stream: impl Read + Send + 'static) -> String {
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stream).lines().map_while(Result::ok) {
            if let Some(at) = line.find("http://") {
                let url = line[at..]
                    .split_whitespace()
                    .next()
                    .unwrap_or("")
                    .to_string();
                let _ = tx.send(url);
            }
        }
    });
    rx.recv_timeout(Duration::from_secs(60))
        .expect("the command printed no URL")
}

/// A raw HTTP request's status line and body.
fn http(url: &str, method: &str, path: &str) -> (String, String) {
    let host = url.trim_start_matches("http://").trim_end_matches('/');
    let mut s = TcpStream::connect(host).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    write!(
        s,
        "{method} {path} HTTP/1.1\r\nHost: {host}\r\nConnection: close\r\nContent-Length: 0\r\n\r\n"
    )
    .unwrap();
    let mut text = String::new();
    let _ = s.read_to_string(&mut text);
    let status = text.lines().next().unwrap_or("").to_string();
    let body = text.split("\r\n\r\n").nth(1).unwrap_or("").to_string();
    (status, body)
}

fn stop(mut child: Child) -> std::process::ExitStatus {
    let pid = nix::unistd::Pid::from_raw(child.id() as i32);
    let _ = nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGINT);
    child.wait().unwrap()
}

#[test]
fn the_live_page_in_a_browser_gains_force_points_and_steps_while_the_run_goes() {
    let Some(browser) = browser() else { return };
    let out = tempfile::tempdir().unwrap();
    // 12 steps of at least a minute each, at 100× real time: about 20 s of wall time.
    let mut child = Command::new(gelrig())
        .arg("run")
        .arg(protocol("portable-normal"))
        .args([
            "--time-scale",
            "100",
            "--plain",
            "--live",
            "127.0.0.1:0",
            "--out",
        ])
        .arg(out.path())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let url = url_from(child.stderr.take().unwrap());
    assert!(url.starts_with("http://127.0.0.1:"), "{url}");
    let page = format!("{url}run/live/");

    let first = dom(browser, &page, 2000);
    let points_1 = attr(&first, "force", "data-points").expect("force plot");
    let steps_1 = attr(&first, "step-counter", "data-steps-done").expect("step counter");
    assert!(
        first.contains("portable-normal"),
        "the page names the protocol"
    );
    // Look again until a step more is done (each takes at least 0.6 s of wall time; on a
    // loaded machine the run may be a few seconds into a frame, and samples wait for it):
    // the page must show the run going on within a minute.
    let deadline = std::time::Instant::now() + Duration::from_secs(60);
    let (second, points_2, steps_2) = loop {
        std::thread::sleep(Duration::from_secs(2));
        let second = dom(browser, &page, 2000);
        let points_2 = attr(&second, "force", "data-points").expect("force plot");
        let steps_2 = attr(&second, "step-counter", "data-steps-done").expect("step counter");
        if (points_2 > points_1 && steps_2 > steps_1) || std::time::Instant::now() > deadline {
            break (second, points_2, steps_2);
        }
    };
    assert!(
        points_2 > points_1 && points_1 > 0,
        "the force plot did not gain points: {points_1} then {points_2}"
    );
    assert!(
        steps_2 > steps_1,
        "the step counter did not advance: {steps_1} then {steps_2}"
    );
    // The latest frame drawn with its markers (portable-normal records a frame per step).
    assert!(
        attr(&second, "frame", "data-arrows").is_some_and(|n| n > 20),
        "no marker arrows on the latest frame"
    );

    // Read-only: no method but GET, and no file outside the report folder.
    let (status, _) = http(&url, "POST", "/run/live/state.json");
    assert!(status.contains(" 405 "), "POST answered {status}");
    let (status, _) = http(&url, "GET", "/run/live/report/..%2F..%2Fetc%2Fpasswd");
    assert!(
        status.contains(" 404 "),
        "a path out of the report answered {status}"
    );
    let (status, body) = http(&url, "GET", "/run/live/state.json");
    assert!(status.contains(" 200 "), "{status}");
    let state: serde_json::Value = serde_json::from_str(&body).expect("state.json");
    assert_eq!(state["meta"]["protocol"], "portable-normal");

    let started = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        assert!(
            started.elapsed() < Duration::from_secs(120),
            "the run did not end"
        );
        std::thread::sleep(Duration::from_millis(200));
    };
    assert!(status.success(), "the run with --live failed: {status}");
}

#[test]
fn gelrig_view_lists_runs_and_opens_a_run_and_its_report() {
    let Some(browser) = browser() else { return };
    let run = shared_dry_run("box-normal-flat");
    let runs = run.parent().unwrap();
    let id = run.file_name().unwrap().to_string_lossy().to_string();
    let mut child = Command::new(gelrig())
        .arg("view")
        .arg(runs)
        .args(["--addr", "127.0.0.1:0"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let url = url_from(child.stdout.take().unwrap());

    // The list of runs, with the run and its status.
    let list = dom(browser, &url, 3000);
    assert_eq!(attr(&list, "runs", "data-count"), Some(1), "one run listed");
    assert!(
        list.contains(&format!(">{id}</a>")) && list.contains(">completed<"),
        "the list does not show the run and its status"
    );
    let (status, body) = http(&url, "GET", "/runs.json");
    assert!(status.contains(" 200 "), "{status}");
    assert!(
        body.contains(&id) && body.contains("\"completed\""),
        "{body}"
    );

    let page = dom(browser, &format!("{url}run/{id}/"), 3000);
    assert!(
        page.contains("box-normal-flat") && page.contains(">completed<"),
        "the run page does not show the run and its status"
    );
    let points = attr(&page, "force", "data-points").expect("force plot");
    let rows = crate::support::csv_rows(&run.join("force.csv")).len() as u64;
    assert_eq!(
        points, rows,
        "the plot holds every force reading of the run"
    );
    assert_eq!(
        attr(&page, "curve", "data-points"),
        Some(crate::support::csv_rows(&run.join("steps.csv")).len() as u64),
        "one point per step on force against position"
    );

    let report = dom(browser, &format!("{url}run/{id}/report/"), 3000);
    assert!(
        report.contains("<h1>") && report.contains("box-normal-flat"),
        "the report did not open"
    );
    assert!(run.join("report").join("report.html").is_file());
    let status = stop(child);
    assert!(
        status.success(),
        "gelrig view did not stop cleanly: {status}"
    );
}

/// Internet (TCP or UDP) sockets process `pid` holds: its socket inodes that appear in the
/// kernel's TCP and UDP tables (the runtime's own Unix socket pairs do not count).
fn inet_sockets(pid: u32) -> usize {
    let proc = Path::new("/proc").join(pid.to_string());
    let Ok(entries) = std::fs::read_dir(proc.join("fd")) else {
        return 0;
    };
    let inodes: Vec<String> = entries
        .flatten()
        .filter_map(|e| {
            let t = std::fs::read_link(e.path()).ok()?;
            let t = t.to_string_lossy();
            Some(
                t.strip_prefix("socket:[")?
                    .trim_end_matches(']')
                    .to_string(),
            )
        })
        .collect();
    let mut tables = String::new();
    for t in ["tcp", "tcp6", "udp", "udp6"] {
        tables += &std::fs::read_to_string(proc.join("net").join(t)).unwrap_or_default();
    }
    tables
        .lines()
        .skip(1)
        .filter_map(|l| l.split_whitespace().nth(9))
        .filter(|inode| inodes.iter().any(|i| i == inode))
        .count()
}

/// The most internet sockets a time-scaled dry run of `portable-normal` holds over its
/// first four seconds, looked at every 0.4 s.
fn sockets_of_a_run(extra: &[&str]) -> usize {
    let out = tempfile::tempdir().unwrap();
    let child = Command::new(gelrig())
        .arg("run")
        .arg(protocol("portable-normal"))
        .args(["--time-scale", "100", "--quiet", "--out"])
        .arg(out.path())
        .args(extra)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut most = 0;
    let mut looked = 0;
    let started = Instant::now();
    while started.elapsed() < Duration::from_secs(4) {
        std::thread::sleep(Duration::from_millis(400));
        if !Path::new("/proc").join(child.id().to_string()).exists() {
            break;
        }
        most = most.max(inet_sockets(child.id()));
        looked += 1;
    }
    assert!(looked >= 5, "the run ended before it could be looked at");
    let _ = stop(child);
    most
}

#[test]
fn a_run_without_live_opens_no_socket() {
    assert_eq!(
        sockets_of_a_run(&[]),
        0,
        "a run without --live opened a socket"
    );
    // The check sees the listening socket of a run with --live.
    assert!(
        sockets_of_a_run(&["--live"]) >= 1,
        "the check cannot see sockets"
    );
}
