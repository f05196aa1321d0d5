//! `gelrig`: run tactile-force experiments on GelSight sensors from YAML protocols. The
//! command itself is [`gelrig::cli`]; this binary only hands it the arguments.

use std::process::ExitCode;

/// mimalloc rather than the system allocator: a dry run allocates and frees frame-sized
/// buffers (a 640×480 frame's 3.7 MB of light levels, the field's transforms) at every frame,
/// and glibc returned them to the kernel and faulted them back each time: 11.8–22 s of
/// system time in a 40–62 s 10-trial lifting-can run (docs/benchmarks/grasp.md). Built
/// without transparent huge pages (`no_thp`): each 2 MB page mimalloc touched first was
/// cleared whole, 15 % of a short dry run's profile samples and 6 % of its wall time
/// (`box-normal-flat`; docs/benchmarks/dry-runs.md).
#[global_allocator]
static ALLOC: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() -> ExitCode {
    gelrig::cli::main(std::env::args_os()).into()
}
