//! The `meshtracer` binary: parse options, run, print the error chain once, exit non-zero.

/// `eprintln!` for the progress, summary, warning and error lines on standard error, which
/// drops a line that cannot be written instead of panicking: after `2>&1 | head -3` the
/// reader has gone, and the render's files and its exit status must not depend on whether it
/// read the summary. There is nowhere else to say that the line was lost.
macro_rules! note {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr(), $($arg)*);
    }};
}

mod cli;
mod commands;

use crate::cli::Cli;
use clap::Parser;
use std::process::ExitCode;

fn main() -> ExitCode {
    keep_freed_memory();
    let cli = Cli::parse();
    match crate::commands::run(cli.command) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            if e.is::<meshtracer::render::Cancelled>() {
                note!("meshtracer: interrupted; no output written");
                return ExitCode::from(130);
            }
            if let Some(stopped) = e.downcast_ref::<crate::commands::Interrupted>() {
                note!("meshtracer: {stopped}");
                return ExitCode::from(130);
            }
            note!("meshtracer: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

/// glibc's malloc gives every block of 128 KiB or more its own `mmap` and unmaps it on free,
/// and trims the heap as soon as 128 KiB at its top are free. A load allocates and frees many
/// such buffers (attribute arrays, per-corner MikkTSpace arrays, sort buffers), so each came
/// back as fresh pages, zeroed by the kernel one page fault at a time. Blocks below
/// `MMAP_THRESHOLD` now come from the heap, which keeps up to `TRIM_THRESHOLD` of freed memory
/// for the next allocation. DamagedHelmet's parse + flatten + tangents (15,452 triangles,
/// median of 21 cold runs each, interleaved, 2 cores): 14.9 -> 12.4 ms on a busy host, and
/// 9.4-10.0 -> 7.8 ms on a quiet one. Larger blocks keep their own mappings, so big models do
/// not hold on to freed memory: MetalRoughSpheresNoTextures' peak resident memory went from 168
/// to 163 MB (32 MiB as the threshold made it 186 MB).
///
/// Only the binary sets this: a library has no business changing its host's allocator.
fn keep_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        /// Largest block served from the heap (larger ones still get their own mapping, and
        /// go back to the system when freed).
        const MMAP_THRESHOLD: libc::c_int = 4 << 20;
        /// Free memory at the top of the heap kept for reuse instead of returned.
        const TRIM_THRESHOLD: libc::c_int = 256 << 20;
        // SAFETY: mallopt only changes malloc's tuning parameters; called before any thread
        // is started. A refused value (returns 0) leaves glibc's default, which is correct,
        // only slower.
        unsafe {
            libc::mallopt(libc::M_MMAP_THRESHOLD, MMAP_THRESHOLD);
            libc::mallopt(libc::M_TRIM_THRESHOLD, TRIM_THRESHOLD);
        }
    }
}
