//! Built-in scenes (placeholder; being written).
