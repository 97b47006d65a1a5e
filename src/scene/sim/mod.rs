//! The room simulator: makes scenes with known truth (filled in by the simulator work).
