//! Simulators of the bench devices.
