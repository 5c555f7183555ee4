//! Built-in smoke plume (placeholder, being written).
