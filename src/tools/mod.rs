//! What users measure meshtracer with: image comparison ([`compare`]), the benchmark workloads
//! ([`bench`](mod@bench)) and their plots ([`plot`]).

pub mod bench;
pub mod compare;
pub mod plot;
