//! mips (placeholder; being written).
