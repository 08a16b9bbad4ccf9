//! # msgs — mrtwin message types
//!
//! Home of the ROS 2 interface package (`msg/*.msg`) and the CDR-compatible Rust types of
//! the twin node's topics. Empty so far: the message set is defined with the twin node
//! (issue 3); the physics core does not need it.
