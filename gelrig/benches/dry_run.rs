//! Wall time of dry runs on the simulated bench in virtual time.
//!
//! Target (issue 2): the shipped box normal protocol — twenty 3-minute settles, an hour on
//! a real bench — finishes in under 10 s of wall time. Each iteration loads, plans and runs
//! a shipped protocol into a fresh temporary run directory, exactly as `gelrig run` does.
//! The table cache is on, as for `gelrig run`: the warm-up fills it and the samples read
//! it (`GELRIG_NO_CACHE=1 cargo bench -p gelrig --bench dry_run` times runs that solve every
//! table; docs/benchmarks/dry-runs.md, "The table cache").

use std::path::Path;

use criterion::{Criterion, criterion_group, criterion_main};
use experiments::load::load;
use experiments::plan::plan;
use runner::{Cancel, Launch, run};

fn dry_run(c: &mut Criterion) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let mut group = c.benchmark_group("dry_run");
    group.sample_size(10);
    for name in [
        "box-normal-flat",
        "box-shear-flat",
        "portable-normal",
        "lifting-can",
    ] {
        let path = root.join("protocols").join(format!("{name}.yaml"));
        let Ok(loaded) = load(&path, None) else {
            panic!("{name} does not load");
        };
        let _p = plan(&loaded.protocol, &loaded.compiled, &loaded.rig);
        group.bench_function(name, |b| {
            b.iter(|| {
                let out = tempfile::tempdir().expect("temp dir");
                let rt = tokio::runtime::Builder::new_current_thread()
                    .enable_all()
                    .start_paused(true)
                    .build()
                    .expect("runtime");
                let outcome = rt
                    .block_on(run(Launch::new(&loaded).out(out.path()), Cancel::new()))
                    .expect("run directory");
                assert_eq!(outcome.status, rundir::write::Status::Completed);
            })
        });
    }
    group.finish();
}

criterion_group!(benches, dry_run);
criterion_main!(benches);
