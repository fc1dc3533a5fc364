#![no_main]
//! Fuzzes the importer with inputs loaded as `model.obj`.

use libfuzzer_sys::fuzz_target;

#[path = "common.rs"]
mod common;

fuzz_target!(|data: &[u8]| common::load("model.obj", data));
