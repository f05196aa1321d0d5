//! The guide cannot drift: every command of every tutorial (`docs/tutorials/*.md`) runs here.
//!
//! Each tutorial's ```` ```bash ```` blocks run in order as one `bash` script
//! (`set -euo pipefail`), in a fresh folder of the tutorial's own set up as its "Before you
//! start" says (a `protocols` link to the shipped protocols), with `gelrig` on the `PATH` as
//! this build's binary; `cargo run --release --bin gelrig -- ARGS` runs the same binary.
//! ```` ```text ```` blocks are output, or commands that need hardware or run until stopped,
//! and are not run. A failure names the tutorial, the line of its Markdown and the command,
//! with the script's stderr. Also: the README's first block is the two commands its test runs,
//! and every relative link of the README, `BENCHMARKS.md` and `docs/` resolves, anchors
//! included.

use std::fs::File;
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use crate::support::{gelrig, root};

/// The tutorials, in the guide's order; `every_tutorial_is_run` keeps this list whole.
const TUTORIALS: [&str; 6] = [
    "first-dry-run",
    "real-bench",
    "grasp-trials",
    "calibrate-the-gelsight",
    "your-own-gel",
    "sweep-campaign",
];

/// A tutorial that has not finished by then is stopped and fails (each takes well under a
/// minute in release).
const LIMIT: Duration = Duration::from_secs(900);

/// Fence languages a tutorial may use: `bash` runs, the others are shown only.
const SHOWN: [&str; 4] = ["text", "yaml", "json", "rust"];

/// One line of a ```` ```bash ```` block: its line in the Markdown file, and its text.
struct Line {
    md_line: usize,
    text: String,
}

/// The ```` ```bash ```` blocks of a tutorial; panics on a fence of another shell-like or no
/// language (a command must say whether it runs) and on an unclosed block.
fn bash_blocks(md: &Path) -> Vec<Vec<Line>> {
    let text = std::fs::read_to_string(md).unwrap();
    let mut blocks = Vec::new();
    let mut open: Option<(bool, Vec<Line>)> = None;
    for (i, line) in text.lines().enumerate() {
        if let Some(lang) = line.trim_start().strip_prefix("```") {
            match open.take() {
                Some((is_bash, lines)) => {
                    assert!(
                        lang.trim().is_empty(),
                        "{}:{}: a fence opens inside a block",
                        md.display(),
                        i + 1
                    );
                    if is_bash {
                        blocks.push(lines);
                    }
                }
                None => {
                    let lang = lang.trim();
                    assert!(
                        lang == "bash" || SHOWN.contains(&lang),
                        "{}:{}: a ``` block of {lang:?}: write ```bash for commands this test \
                         runs, ```text for output or commands that need hardware",
                        md.display(),
                        i + 1
                    );
                    open = Some((lang == "bash", Vec::new()));
                }
            }
        } else if let Some((_, lines)) = open.as_mut() {
            lines.push(Line {
                md_line: i + 1,
                text: line.to_string(),
            });
        }
    }
    assert!(
        open.is_none(),
        "{}: a ``` block is not closed",
        md.display()
    );
    blocks
}

/// What every script starts with: strict mode, the failing line reported, background jobs
/// (a `sim serve`) stopped on the way out, and `cargo run --release --bin gelrig --` as
/// `gelrig`.
const PREAMBLE: &str = r#"set -euo pipefail
trap 'echo "guide: failed at script line $LINENO (exit $?)" >&2' ERR
trap 'jobs -p | xargs -r kill 2>/dev/null || true' EXIT
cargo() {
  if [ "$#" -ge 5 ] && [ "$1 $2 $3 $4 $5" = "run --release --bin gelrig --" ]; then
    shift 5; gelrig "$@"
  else
    echo "guide: only 'cargo run --release --bin gelrig -- …' runs here, not: cargo $*" >&2; return 2
  fi
}
set -x
"#;

/// Runs one tutorial and panics naming the line that failed.
fn run_tutorial(name: &str) {
    let md = root().join("docs/tutorials").join(format!("{name}.md"));
    let blocks = bash_blocks(&md);
    assert!(
        !blocks.is_empty(),
        "{}: no ```bash block, so nothing of it is checked",
        md.display()
    );

    let tmp = tempfile::Builder::new()
        .prefix(&format!("guide-{name}-"))
        .tempdir()
        .unwrap();
    let bin = tmp.path().join("bin");
    let work = tmp.path().join("work");
    std::fs::create_dir_all(&bin).unwrap();
    std::fs::create_dir_all(&work).unwrap();
    std::os::unix::fs::symlink(gelrig(), bin.join("gelrig")).unwrap();
    std::os::unix::fs::symlink(root().join("protocols"), work.join("protocols")).unwrap();

    // The script, and for each of its lines the Markdown line it came from.
    let mut script = String::from(PREAMBLE);
    let mut origin: Vec<Option<usize>> = vec![None; PREAMBLE.lines().count()];
    for block in &blocks {
        script.push_str(&format!("# {name}.md:{}\n", block[0].md_line - 1));
        origin.push(Some(block[0].md_line));
        for line in block {
            script.push_str(&line.text);
            script.push('\n');
            origin.push(Some(line.md_line));
        }
    }
    let script_path = tmp.path().join("tutorial.sh");
    std::fs::write(&script_path, &script).unwrap();
    let out_path = tmp.path().join("stdout");
    let err_path = tmp.path().join("stderr");

    let path = std::env::join_paths(std::iter::once(bin).chain(std::env::split_paths(
        &std::env::var_os("PATH").unwrap_or_default(),
    )))
    .unwrap();
    let started = Instant::now();
    let mut child = Command::new("bash")
        .arg(&script_path)
        .current_dir(&work)
        .env("PATH", path)
        .stdin(std::process::Stdio::null())
        .stdout(File::create(&out_path).unwrap())
        .stderr(File::create(&err_path).unwrap())
        // Its own process group, so whatever it leaves running is stopped with it.
        .process_group(0)
        .spawn()
        .unwrap();
    let group = nix::unistd::Pid::from_raw(child.id() as i32);
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break Some(status);
        }
        if started.elapsed() > LIMIT {
            break None;
        }
        std::thread::sleep(Duration::from_millis(100));
    };
    let _ = nix::sys::signal::killpg(group, nix::sys::signal::Signal::SIGKILL);
    let _ = child.wait();
    let took = started.elapsed().as_secs_f64();
    eprintln!("guide: docs/tutorials/{name}.md ran in {took:.1} s");

    let stderr = std::fs::read_to_string(&err_path).unwrap_or_default();
    let tail = |text: &str, n: usize| {
        let lines: Vec<&str> = text.lines().collect();
        lines[lines.len().saturating_sub(n)..].join("\n")
    };
    let Some(status) = status else {
        panic!(
            "docs/tutorials/{name}.md did not finish in {} s; its stderr ends:\n{}",
            LIMIT.as_secs(),
            tail(&stderr, 60)
        );
    };
    if status.success() {
        return;
    }
    // The ERR trap names the script line; map it back to the Markdown.
    let failed = stderr
        .lines()
        .rev()
        .find_map(|l| l.strip_prefix("guide: failed at script line "))
        .and_then(|rest| rest.split_whitespace().next())
        .and_then(|n| n.parse::<usize>().ok())
        .and_then(|n| origin.get(n.checked_sub(1)?).copied().flatten());
    let at = match failed {
        Some(md_line) => {
            let text = blocks
                .iter()
                .flatten()
                .find(|l| l.md_line == md_line)
                .map_or("", |l| l.text.as_str());
            format!("line {md_line}: `{}`", text.trim())
        }
        None => "a line the script could not name".to_string(),
    };
    panic!(
        "docs/tutorials/{name}.md, {at}, failed ({status}); stdout ends:\n{}\n--- stderr ends:\n{}",
        tail(&std::fs::read_to_string(&out_path).unwrap_or_default(), 20),
        tail(&stderr, 60)
    );
}

#[test]
fn every_tutorial_is_run() {
    let mut found: Vec<String> = std::fs::read_dir(root().join("docs/tutorials"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|x| x == "md"))
        .map(|p| p.file_stem().unwrap().to_string_lossy().into_owned())
        .collect();
    found.sort();
    let mut listed: Vec<String> = TUTORIALS.iter().map(|s| s.to_string()).collect();
    listed.sort();
    assert_eq!(
        found, listed,
        "docs/tutorials/ and this file's TUTORIALS differ: add a test for each new tutorial"
    );
    for name in TUTORIALS {
        let md = root().join("docs/tutorials").join(format!("{name}.md"));
        assert!(
            !bash_blocks(&md).is_empty(),
            "{}: no ```bash block, so nothing of it is checked",
            md.display()
        );
    }
}

#[test]
fn tutorial_sweep_campaign() {
    run_tutorial("sweep-campaign");
}

#[test]
fn tutorial_first_dry_run() {
    run_tutorial("first-dry-run");
}

#[test]
fn tutorial_real_bench() {
    run_tutorial("real-bench");
}

#[test]
fn tutorial_grasp_trials() {
    run_tutorial("grasp-trials");
}

#[test]
fn tutorial_calibrate_the_gelsight() {
    run_tutorial("calibrate-the-gelsight");
}

#[test]
fn tutorial_your_own_gel() {
    run_tutorial("your-own-gel");
}

/// The README's first code block is the two commands a newcomer types, and the first is the
/// one `dry_run::the_readme_command_runs_box_normal_flat` runs.
#[test]
fn the_readme_opens_with_the_two_commands() {
    let readme = std::fs::read_to_string(root().join("README.md")).unwrap();
    let start = readme.find("```").expect("README has a code block");
    let body = &readme[start..];
    let body = &body[body.find('\n').unwrap() + 1..];
    let block = &body[..body.find("```").expect("the block is closed")];
    assert_eq!(
        block,
        "cargo run --release --bin gelrig -- run protocols/box-normal-flat.yaml\n\
         cargo test --workspace\n"
    );
    assert!(
        readme[..start].lines().count() < 40,
        "the two commands are on the first screen"
    );
}

/// GitHub's anchor for a heading: lower case, punctuation dropped, spaces as hyphens.
fn anchor(heading: &str) -> String {
    let mut text = String::new();
    // Link text stays, its target goes; code spans lose their backticks.
    let mut rest = heading;
    while let Some(open) = rest.find('[') {
        text.push_str(&rest[..open]);
        let after = &rest[open + 1..];
        match (after.find("]("), after.find(')')) {
            (Some(close), Some(end)) if close < end => {
                text.push_str(&after[..close]);
                rest = &after[end + 1..];
            }
            _ => {
                text.push('[');
                rest = after;
            }
        }
    }
    text.push_str(rest);
    text.trim()
        .to_lowercase()
        .chars()
        .filter(|c| c.is_alphanumeric() || matches!(c, ' ' | '-' | '_'))
        .map(|c| if c == ' ' { '-' } else { c })
        .collect()
}

/// The anchors of a Markdown file's headings (a repeated one as `-1`, `-2`, …).
fn anchors(md: &Path) -> std::collections::BTreeSet<String> {
    let text = std::fs::read_to_string(md).unwrap();
    let mut seen = std::collections::BTreeMap::<String, usize>::new();
    let mut out = std::collections::BTreeSet::new();
    let mut in_code = false;
    for line in text.lines() {
        if line.starts_with("```") {
            in_code = !in_code;
            continue;
        }
        if in_code {
            continue;
        }
        let hashes = line.chars().take_while(|&c| c == '#').count();
        if (1..=6).contains(&hashes) && line[hashes..].starts_with(' ') {
            let a = anchor(&line[hashes..]);
            let n = seen.entry(a.clone()).or_insert(0);
            out.insert(if *n == 0 {
                a.clone()
            } else {
                format!("{a}-{n}")
            });
            *n += 1;
        }
    }
    out
}

fn markdown_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            markdown_files(&p, out);
        } else if p.extension().is_some_and(|x| x == "md") {
            out.push(p);
        }
    }
}

#[test]
fn every_link_of_the_guide_resolves() {
    let root = root();
    let mut files = vec![root.join("README.md"), root.join("BENCHMARKS.md")];
    markdown_files(&root.join("docs"), &mut files);
    let mut broken = Vec::new();
    for md in &files {
        let text = std::fs::read_to_string(md).unwrap();
        let mut in_code = false;
        for (i, line) in text.lines().enumerate() {
            if line.starts_with("```") {
                in_code = !in_code;
                continue;
            }
            if in_code {
                continue;
            }
            for (at, _) in line.match_indices("](") {
                let target = &line[at + 2..];
                let Some(end) = target.find(')') else {
                    continue;
                };
                let target = &target[..end];
                if target.contains("://") || target.starts_with("mailto:") || target.contains(' ') {
                    continue;
                }
                let (file, frag) = target.split_once('#').unwrap_or((target, ""));
                let dest = if file.is_empty() {
                    md.clone()
                } else {
                    md.parent().unwrap().join(file)
                };
                let place = format!("{}:{}", md.strip_prefix(&root).unwrap().display(), i + 1);
                if !dest.exists() {
                    broken.push(format!("{place}: {target} (no such file)"));
                } else if !frag.is_empty()
                    && dest.extension().is_some_and(|x| x == "md")
                    && !anchors(&dest).contains(frag)
                {
                    broken.push(format!("{place}: {target} (no such heading)"));
                }
            }
        }
    }
    assert!(broken.is_empty(), "broken links:\n{}", broken.join("\n"));
}
