//! Sweep files into points: every design, the names, the shards, and refusals that name the
//! key at fault.

// A test fails by panicking: unwrapping is how it says what broke.
#![allow(clippy::unwrap_used)]

use std::path::Path;

use campaign::{Shard, Sweep, points};

fn sweep(text: &str) -> Result<Sweep, String> {
    Sweep::parse(text, Path::new("/lab/sweeps/s.yaml")).map_err(|e| e.to_string())
}

#[test]
fn a_grid_is_every_combination_the_last_key_fastest() {
    let s = sweep(
        "sweep: punch\nprotocol: box-normal-flat\nset: {approach.speed: 2 mm/s}\ngrid:\n  indenter.diameter: [6 mm, 9.5 mm]\n  seed: [1, 2, 3]\n",
    )
    .unwrap();
    assert_eq!(
        s.protocol,
        Path::new("box-normal-flat"),
        "a shipped name stays a name"
    );
    let p = points(&s).unwrap();
    assert_eq!(p.len(), 6);
    assert_eq!(p[0].name, "0000_diameter-6mm_seed-1");
    assert_eq!(p[1].name, "0001_diameter-6mm_seed-2");
    assert_eq!(p[3].name, "0003_diameter-9.5mm_seed-1");
    assert_eq!(p[4].seed, 2);
    assert_eq!(
        p[4].set,
        vec!["approach.speed=2 mm/s", "indenter.diameter=9.5 mm"]
    );
    let names: std::collections::BTreeSet<_> = p.iter().map(|p| &p.name).collect();
    assert_eq!(names.len(), 6);
}

/// A mapping value (a whole indenter) names its point by its values, and a name is cut to
/// the 64 characters a run's name may have.
#[test]
fn mapping_values_name_points_by_their_values_within_a_runs_name() {
    let s = sweep(
        "sweep: x\nprotocol: p\ngrid:\n  indenter:\n    - {shape: cylinder, diameter: 4 mm, length: 15 mm}\n  sequence.3.stepped.a_very_long_parameter_name: [a value long enough to be cut]\n",
    )
    .unwrap();
    let p = points(&s).unwrap();
    assert!(
        p[0].name
            .starts_with("0000_indenter-4mm-15mm-cylinder_a_very_long"),
        "{}",
        p[0].name
    );
    assert_eq!(p[0].name.len(), 64, "{}", p[0].name);
    assert!(p[0].set[0].starts_with("indenter={"), "{:?}", p[0].set);
}

#[test]
fn a_path_is_taken_from_the_sweep_files_folder() {
    let s = sweep("sweep: x\nprotocol: ../protocols/mine.yaml\nlist: [{seed: 4}]\n").unwrap();
    assert_eq!(s.protocol, Path::new("/lab/sweeps/../protocols/mine.yaml"));
    assert_eq!(points(&s).unwrap()[0].seed, 4);
}

#[test]
fn random_and_latin_hypercube_draws_are_in_range_and_reproducible() {
    let text = |kind: &str| {
        format!(
            "sweep: x\nprotocol: p\n{kind}:\n  n: 40\n  seed: 7\n  parameters:\n    indenter.diameter: {{from: 5 mm, to: 10 mm}}\n    seed: {{from: 1, to: 1000}}\n"
        )
    };
    for kind in ["random", "latin_hypercube"] {
        let a = points(&sweep(&text(kind)).unwrap()).unwrap();
        let b = points(&sweep(&text(kind)).unwrap()).unwrap();
        assert_eq!(a, b, "{kind}: the same seed, the same points");
        assert_eq!(a.len(), 40);
        let mut diameters = Vec::new();
        for p in &a {
            let d = &p.params[0].1;
            let mm: f64 = d.strip_suffix(" mm").unwrap().parse().unwrap();
            assert!((5.0..10.0).contains(&mm), "{d}");
            assert!((1..=1000).contains(&p.seed));
            diameters.push(mm);
        }
        if kind == "latin_hypercube" {
            // One point in each of the 40 strata of the range.
            let mut strata: Vec<usize> = diameters
                .iter()
                .map(|d| ((d - 5.0) / 5.0 * 40.0) as usize)
                .collect();
            strata.sort_unstable();
            assert_eq!(strata, (0..40).collect::<Vec<_>>());
        }
    }
    let other = text("random").replace("seed: 7", "seed: 8");
    assert_ne!(
        points(&sweep(&text("random")).unwrap()).unwrap(),
        points(&sweep(&other).unwrap()).unwrap()
    );
}

#[test]
fn shards_split_the_points_evenly_and_completely() {
    let s = sweep("sweep: x\nprotocol: p\ngrid: {seed: [1,2,3,4,5,6,7,8,9,10,11]}\n").unwrap();
    let p = points(&s).unwrap();
    let mut seen = vec![0; p.len()];
    for i in 1..=4 {
        let shard = Shard::parse(&format!("{i}/4")).unwrap();
        let mine: Vec<usize> = (0..p.len()).filter(|k| shard.has(*k)).collect();
        assert!((2..=3).contains(&mine.len()), "{mine:?}");
        for k in mine {
            seen[k] += 1;
        }
    }
    assert!(seen.iter().all(|n| *n == 1));
    let env = |pairs: &'static [(&'static str, &'static str)]| {
        move |k: &str| {
            pairs
                .iter()
                .find(|(n, _)| *n == k)
                .map(|(_, v)| v.to_string())
        }
    };
    let slurm = Shard::from_env(env(&[
        ("SLURM_ARRAY_TASK_ID", "2"),
        ("SLURM_ARRAY_TASK_COUNT", "4"),
    ]));
    assert_eq!(slurm.unwrap(), Some(Shard { index: 3, count: 4 }));
    let k8s = Shard::from_env(env(&[
        ("JOB_COMPLETION_INDEX", "0"),
        ("JOB_COMPLETIONS", "2"),
    ]));
    assert_eq!(k8s.unwrap(), Some(Shard { index: 1, count: 2 }));
    assert_eq!(Shard::from_env(env(&[])).unwrap(), None);
    let e = Shard::from_env(env(&[("JOB_COMPLETION_INDEX", "1")])).unwrap_err();
    assert!(e.to_string().contains("JOB_COMPLETIONS"), "{e}");
    for bad in ["0/4", "5/4", "2", "a/b"] {
        assert!(Shard::parse(bad).unwrap_err().to_string().contains("I/N"));
    }
}

#[test]
fn a_bad_sweep_file_is_refused_naming_the_key_and_the_fix() {
    let cases = [
        ("protocol: p\ngrid: {seed: [1]}\n", "sweep"),
        ("sweep: x\ngrid: {seed: [1]}\n", "protocol"),
        ("sweep: x\nprotocol: p\n", "no design"),
        (
            "sweep: x\nprotocol: p\ngrid: {seed: [1]}\nlist: [{seed: 1}]\n",
            "2 designs",
        ),
        (
            "sweep: x\nprotocol: p\ngrid: {seed: []}\n",
            "grid.seed: an empty list",
        ),
        (
            "sweep: x\nprotocol: p\nrandom: {n: 3, seed: 1, parameters: {depth: {from: 2 mm, to: 1 mm}}}\n",
            "random.parameters.depth",
        ),
        (
            "sweep: x\nprotocol: p\nrandom: {n: 3, seed: 1, parameters: {depth: {from: 1 mm, to: 2 N}}}\n",
            "one unit",
        ),
        (
            "sweep: x\nprotocol: p\nlatin_hypercube: {seed: 1, parameters: {depth: {from: 1, to: 2}}}\n",
            "latin_hypercube.n",
        ),
        (
            "sweep: x\nprotocol: p\ngrid: {seed: [1]}\nresources: {memory: 2 parsecs}\n",
            "resources.memory",
        ),
        (
            "sweep: x\nprotocol: p\ngrid: {seed: [1]}\nsweeps: 3\n",
            "unknown key",
        ),
        (
            "sweep: x\nprotocol: p\ngrid: {seed: [1, 2, 3, 4, 5, 6, 7, 8, 9, 10], a: [1,2,3,4,5,6,7,8,9,10], b: [1,2,3,4,5,6,7,8,9,10], c: [1,2,3,4,5,6,7,8,9,10], d: [1,2,3,4,5,6,7,8,9,10], e: [1,2,3,4,5,6,7,8,9,10], f: [1,2]}\n",
            "more than",
        ),
    ];
    for (text, want) in cases {
        let e = sweep(text).unwrap_err();
        assert!(
            e.contains("/lab/sweeps/s.yaml") && e.contains(want),
            "{text}: {e}"
        );
    }
    let s = sweep("sweep: x\nprotocol: p\nlist: [{seed: -1}]\n").unwrap();
    assert!(points(&s).unwrap_err().contains("seed"));
}

#[test]
fn resources_set_the_clusters_time_and_memory() {
    let s = sweep("sweep: x\nprotocol: p\ngrid: {seed: [1]}\nresources: {time_per_point: 2 min, memory: 1.5 GB}\n").unwrap();
    assert_eq!((s.time_per_point_s, s.memory_mb), (120.0, 1536));
}

#[test]
fn a_mapping_value_goes_to_set_as_flow_yaml() {
    let s = sweep(
        "sweep: x\nprotocol: p\nset: {sequence.3.stepped.capture: {force_window: 10 s, frames: 10}}\ngrid:\n  sequence.3.stepped.settle: [{fixed: 60 s}, {fixed: 120 s}]\n",
    )
    .unwrap();
    let p = points(&s).unwrap();
    assert_eq!(p.len(), 2);
    assert_eq!(
        p[1].set,
        vec![
            r#"sequence.3.stepped.capture={"force_window":"10 s","frames":10}"#,
            r#"sequence.3.stepped.settle={"fixed":"120 s"}"#
        ]
    );
}
