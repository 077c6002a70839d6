//! SUMO co-simulation for syncroad (placeholder).
