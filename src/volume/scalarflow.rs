//! ScalarFlow loader (placeholder, being written).
