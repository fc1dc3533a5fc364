#![no_main]
//! Fuzzes zip archives: unpacked from disk, their one model loaded with the files beside it.

use libfuzzer_sys::fuzz_target;

#[path = "common.rs"]
mod common;

fuzz_target!(|data: &[u8]| common::load_archive(data));
