//! `bench` CLI (being assembled).
fn main() {}
