//! The page's module gets a stack of [`STACK_BYTES`]: a frame of the demo
//! (the page update's write list, the scene's page images) needs about
//! 2 MiB in a test build, more than WebAssembly's default of 1 MiB.

/// The module's stack. Memory only, not page weight: the file holds none of it.
const STACK_BYTES: u32 = 8 << 20;

fn main() {
    if std::env::var("CARGO_CFG_TARGET_ARCH").as_deref() == Ok("wasm32") {
        println!("cargo:rustc-link-arg-cdylib=-zstack-size={STACK_BYTES}");
    }
    println!("cargo:rerun-if-changed=build.rs");
}
