//! The one way to cancel long work: a [`Cancel`] that every long pass polls
//! (per row or block of rows) and [`Cancelled`], what a pass returns once it
//! said yes. The lowest layer: it depends on nothing.

use std::fmt;

/// A cancellation probe, passed by value to every long pass. Polled per row
/// or block of rows; once it says yes the pass stops and returns
/// [`Cancelled`] (whatever it had written is then incomplete).
#[derive(Clone, Copy)]
pub struct Cancel<'a>(Option<&'a (dyn Fn() -> bool + Sync)>);

impl<'a> Cancel<'a> {
    /// Never cancels: the pass always completes.
    pub const NEVER: Cancel<'static> = Cancel(None);

    /// Cancels once `probe` returns true (it is called from several threads,
    /// often: keep it to an atomic load or two).
    pub fn new(probe: &'a (dyn Fn() -> bool + Sync)) -> Self {
        Self(Some(probe))
    }

    /// Whether the work should stop now.
    #[inline]
    pub fn is_cancelled(self) -> bool {
        self.0.is_some_and(|probe| probe())
    }

    /// `Err(Cancelled)` once the work should stop.
    #[inline]
    pub fn check(self) -> Result<(), Cancelled> {
        if self.is_cancelled() {
            Err(Cancelled)
        } else {
            Ok(())
        }
    }
}

impl fmt::Debug for Cancel<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(if self.0.is_some() {
            "Cancel(probe)"
        } else {
            "Cancel::NEVER"
        })
    }
}

/// A long pass stopped because its [`Cancel`] said so.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("cancelled")]
pub struct Cancelled;

/// The value of a pass run with [`Cancel::NEVER`], which always completes.
pub trait Uncancelled<T> {
    /// The value; a pass given [`Cancel::NEVER`] cannot return [`Cancelled`].
    fn uncancelled(self) -> T;
}

impl<T> Uncancelled<T> for Result<T, Cancelled> {
    fn uncancelled(self) -> T {
        match self {
            Ok(value) => value,
            Err(Cancelled) => unreachable!("a pass given Cancel::NEVER completes"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicBool, Ordering};

    #[test]
    fn never_never_cancels_and_a_probe_is_read_each_time() {
        assert!(!Cancel::NEVER.is_cancelled());
        assert_eq!(Cancel::NEVER.check(), Ok(()));
        let stop = AtomicBool::new(false);
        let probe = || stop.load(Ordering::Relaxed);
        let cancel = Cancel::new(&probe);
        assert_eq!(cancel.check(), Ok(()));
        stop.store(true, Ordering::Relaxed);
        assert!(cancel.is_cancelled());
        assert_eq!(cancel.check(), Err(Cancelled));
        assert_eq!(Ok::<_, Cancelled>(3).uncancelled(), 3);
    }
}
