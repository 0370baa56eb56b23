//! The sweep's I/O error: a file or folder that could not be written. Its own file so that every
//! part of the sweep that writes (`mod.rs`, `runner.rs`, `plots.rs`) takes it from here and none
//! imports another for it.

use std::path::Path;

use forestlod_reference::InputError;

/// The error of a failed write of `path` (its I/O error as the reason).
pub(super) fn io_err(path: &Path, e: impl std::fmt::Display) -> InputError {
    InputError::new(path.display().to_string(), "write", "", e.to_string())
}
