//! User scenes (placeholder; being written).
