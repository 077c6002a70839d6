//! Velocity-synchronization laws for microscopic traffic (placeholder, filled in by the foundation work).

pub mod exact;
