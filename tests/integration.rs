//! The integration tests, as one test binary: each file of `tests/` is a module of it.
//!
//! One binary instead of one per file, for the 2-core CI machine: each separate test binary was
//! linked against the whole library and its dependencies (34 links), and `cargo test` runs test
//! binaries one after another, so a binary whose last test ran alone left the second core idle
//! (the eFAST file: 81 s wall for 69 CPU-seconds). In one binary the harness keeps both cores
//! busy to the end. Tests that share something outside the process take a lock for it
//! (`common::vcan0`, one Ray cluster at a time in `common::ray`).
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
