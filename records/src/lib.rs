//! What gelrig measures and records, as plain data: quantities with explicit units as
//! protocol and rig files write them ([`units`]), and the readings devices hand over and run
//! directories keep ([`readings`]: force samples, frames, the simulated bench's truth,
//! device timing). Nothing here drives hardware or solves contact: the device layer
//! (`rig`), the simulated bench (`simbench`) and the run directory format (`rundir`) all
//! build on it.

pub mod readings;
pub mod units;

pub use readings::{
    DeviceTiming, ForceSample, Frame, GraspTruth, STATUS_SATURATED, SimTruth, SurfaceTruth, Wrench,
};

/// Device text as it may appear in a message: a garbled reply can be megabytes of
/// anything, and a message quoting it whole would flood the terminal, `run.yaml` and the
/// journal. At most 120 characters, control characters escaped, and the full length said
/// when cut.
pub fn quote(text: &str) -> String {
    const MAX_CHARS: usize = 120;
    let mut out = String::new();
    for (shown, c) in text.chars().enumerate() {
        if shown == MAX_CHARS {
            out.push_str(&format!("… ({} bytes)", text.len()));
            return out;
        }
        if c.is_control() {
            out.extend(c.escape_default());
        } else {
            out.push(c);
        }
    }
    out
}

/// Locks a mutex shared between simulated devices, recovering from poisoning: a panic in
/// one device must not take the rest of the bench (and the run's data) down with it.
pub fn lock<T>(m: &std::sync::Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

#[cfg(test)]
mod tests {
    #[test]
    fn quotes_are_short_and_printable() {
        assert_eq!(super::quote("1TPNaN"), "1TPNaN");
        assert_eq!(super::quote("a\r\n\u{7}b"), "a\\r\\n\\u{7}b");
        let flood = "x".repeat(4 << 20);
        let q = super::quote(&flood);
        assert!(
            q.chars().count() < 140 && q.ends_with("(4194304 bytes)"),
            "{q}"
        );
    }
}
