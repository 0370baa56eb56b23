//! placeholder
pub use forestlod_shared as shared;
