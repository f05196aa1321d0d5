//! Twins: simulators that speak a real device's wire protocol over a real transport
//! (pseudo-terminal, loopback socket), so tests and `gelrig sim serve` exercise the
//! production drivers unchanged, including their handling of injected faults.

pub mod ati_can;
pub mod modbus;
pub mod motion;
pub mod netft;
pub mod pty;
pub mod smc100;
pub mod zaber;
