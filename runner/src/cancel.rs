//! The operator's interrupts (Ctrl-C, SIGTERM), counted and waited for.
//!
//! A count, not a flag: the first interrupt aborts the run and retracts, a second one gives
//! up the retract. Waiting is part of it: every wait of the run selects on
//! [`Cancel::interrupted`], so an interrupt takes effect at once even in the middle of a
//! three-minute settle on a rig with no force sensor to wake the loop, or on a clock
//! scaled so slow that the next due event is hours of wall time away.

use std::sync::Arc;
use std::sync::atomic::{AtomicU32, Ordering};

use tokio::sync::Notify;

#[derive(Debug, Default)]
struct Inner {
    count: AtomicU32,
    notify: Notify,
}

/// Interrupt requests from signal handlers (count of SIGINT/SIGTERM received).
#[derive(Debug, Clone, Default)]
pub struct Cancel(Arc<Inner>);

impl Cancel {
    /// A fresh token.
    pub fn new() -> Self {
        Self::default()
    }

    /// Records one interrupt request and wakes every waiter. Safe to call from any thread
    /// or runtime.
    pub fn interrupt(&self) {
        self.0.count.fetch_add(1, Ordering::SeqCst);
        self.0.notify.notify_waiters();
    }

    /// Interrupts requested so far.
    pub fn count(&self) -> u32 {
        self.0.count.load(Ordering::SeqCst)
    }

    /// Resolves once more than `seen` interrupts have been requested.
    pub async fn interrupted(&self, seen: u32) {
        loop {
            let notified = self.0.notify.notified();
            tokio::pin!(notified);
            // Registered before the count is read, so an interrupt in between is not lost.
            notified.as_mut().enable();
            if self.count() > seen {
                return;
            }
            notified.await;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn an_interrupt_from_another_thread_wakes_a_long_wait() {
        let c = Cancel::new();
        let c2 = c.clone();
        std::thread::spawn(move || {
            std::thread::sleep(std::time::Duration::from_millis(20));
            c2.interrupt();
        });
        tokio::select! {
            _ = c.interrupted(0) => {}
            _ = tokio::time::sleep(std::time::Duration::from_secs(3600)) => {
                panic!("the hour-long sleep won over the interrupt")
            }
        }
        assert_eq!(c.count(), 1);
    }
}
