//! The integration tests, as one test binary: each file of `tests/` is a module of it.
//!
//! One binary instead of one per file, for two reasons measured on the 2-core CI machine. Every
//! separate test binary is compiled and linked against the whole library and its dependencies,
//! which made linking a large share of the test build. And `cargo test` runs test binaries one
//! after another: a binary whose last test runs alone (a gap study, a campaign waiting on its
//! cluster) left the second core idle, while in one binary the test harness keeps both busy.
//! Run one file's tests with `cargo test --test integration gap_footprint::`.

mod common;
mod room;

mod bad_input;
mod bag_interop;
mod campaign;
mod can_cantools;
mod can_ego;
mod can_socketcan;
mod check;
mod compare;
mod decode_cli;
mod demo;
mod efast_interop;
mod fixtures;
mod gap;
mod gap_effects;
mod gap_engine;
mod gap_footprint;
mod gnss_gpsd;
mod gnss_serial;
mod layout;
mod missing_inputs;
mod non_finite;
mod parking;
mod record_from;
mod record_live;
mod replay;
mod replay_memory;
mod resim;
mod sim_model;
mod stats_interop;
mod udp_source;
mod validate;
mod velodyne_interop;
mod velodyne_real;
mod vls128;
