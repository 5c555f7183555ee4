//! Reference volumetric path tracer (placeholder, being written).
