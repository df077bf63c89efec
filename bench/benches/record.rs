//! Recorder throughput (filled in below).
fn main() {}
