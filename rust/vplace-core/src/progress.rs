//! Progress and cancellation of a long call, shared between the caller and the worker threads
//! (the evaluator, the layout iterations, the refit, the direct-light estimator, PAR 2D).

use std::sync::atomic::{AtomicBool, AtomicUsize};

/// Progress and cancellation shared with the caller, polled between tiles.
#[derive(Debug, Default)]
pub struct Progress {
    /// Work items finished (tiles for the evaluator).
    pub done: AtomicUsize,
    /// Work items in all, set when the work starts.
    pub total: AtomicUsize,
    /// Set by the caller to stop the work; the call then returns [`crate::VplaceError::Cancelled`].
    pub cancel: AtomicBool,
}
