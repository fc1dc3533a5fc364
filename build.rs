//! Build script: with the `denoise` feature only, records where Open Image Denoise lives as
//! the binaries' run path, so `meshtracer --denoise` runs without LD_LIBRARY_PATH. The `oidn`
//! crate's own build script does the linking (from `$OIDN_DIR/lib`); without the feature this
//! does nothing.

use std::path::Path;

fn main() {
    // Without a rerun-if line cargo would rerun this after any change in the package.
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-env-changed=OIDN_DIR");
    if std::env::var_os("CARGO_FEATURE_DENOISE").is_none() {
        return;
    }
    let Some(dir) = std::env::var_os("OIDN_DIR").filter(|d| !d.is_empty()) else {
        // The oidn crate found the library through pkg-config (a system installation), which
        // the dynamic loader finds by itself.
        return;
    };
    let lib = Path::new(&dir).join("lib");
    if !lib.is_absolute() {
        println!(
            "cargo:warning=OIDN_DIR={} is relative: the oidn crate resolves it from its own \
             folder; give an absolute path (scripts/oidn/fetch.sh prints one)",
            Path::new(&dir).display()
        );
        return;
    }
    if std::env::var("CARGO_CFG_TARGET_OS").is_ok_and(|os| os == "linux") {
        // An absolute run path: the binary finds the library wherever it is started from, and
        // stops finding it if the folder moves (then set LD_LIBRARY_PATH, see docs/denoising.md).
        println!("cargo:rustc-link-arg=-Wl,-rpath,{}", lib.display());
    }
}
