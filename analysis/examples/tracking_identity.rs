//! The identity table: condition × method × identity / recall / rms / speed, on synthetic
//! scenes with exact truth (`rig::sim::scenes`): pans with markers leaving and entering the
//! view, jumps from rest, a twist inside the contact, whole-view rotation, and exposure,
//! contrast, defocus and noise. Scoring is in `tests/common/identity.rs`, shared with the
//! tests that hold the targets.
//!
//! Run: `cargo run --release -p analysis --example tracking_identity`
//! (`-- centroid` for one method).

#[path = "../tests/common/identity.rs"]
mod identity;

use analysis::tracking::Method;

fn main() {
    let only: Option<String> = std::env::args().nth(1);
    let filter: Option<String> = std::env::args().nth(2);
    let methods = [
        ("centroid", Method::Centroid),
        ("centroid+lk", Method::CentroidLk),
        ("lk", Method::Lk),
    ];
    println!(
        "| condition | method | identity among measured | measured of visible | ambiguous | rms (px) | rest (px) | ms/frame |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for c in identity::conditions() {
        if filter.as_deref().is_some_and(|f| !c.name.contains(f)) {
            continue;
        }
        for (name, method) in methods {
            if only.as_deref().is_some_and(|o| o != name) {
                continue;
            }
            let s = identity::score(&c, method);
            if let Some(why) = &s.refused {
                println!("| {} | {name} | refused: {why} | | | | | |", c.name);
                continue;
            }
            println!(
                "| {} | {name} | {:.2} % ({} wrong of {}) | {:.1} % | {} | {:.3} | {:.3} | {:.2} |",
                c.name,
                100.0 * s.identity(),
                s.wrong,
                s.claimed,
                100.0 * s.recall(),
                s.ambiguous,
                s.rms(),
                s.rest_px,
                s.ms_per_frame
            );
        }
    }
}
