//! The cube demo, the VGA inspector and a slow-motion view of every bus
//! operation as a web page: this crate built for `wasm32-unknown-unknown` is
//! the page's module, and on the host it builds and serves the page.
//!
//! All the page's logic is here, in Rust, and tested on the host; the page's
//! JavaScript (`web/page/modex.js`) only moves events in and pixels out:
//!
//! * [`keys`]: `KeyboardEvent.code` to the runner's key names and set-1 scan codes;
//! * [`url`]: the URL's replay script (`?keys=left,up&frames=120&paused=1`);
//! * [`pacing`]: frames on `requestAnimationFrame` at the model's retrace rate;
//! * [`hover`]: the readout for the pixel under the mouse;
//! * [`lab`]: the register lab, every VGA register edited in place;
//! * [`slow`]: one frame's bus operations stepped one by one, named by the
//!   `modex` function that issued each;
//! * [`page`]: the page's state, which the WebAssembly exports drive;
//! * `book`, `build` and `serve` (host only): the book rendered into the
//!   page, the page's files, and a local server.
//!
//! The exports use no `wasm-bindgen`: plain `extern "C"` functions and
//! buffers in the module's linear memory (`web/page/modex.js` reads them);
//! `docs/web.md` lists them.
//!
//! ```
//! use web::page::Page;
//!
//! // The page as `?keys=m&frames=3` loads it: three objects, three frames.
//! let mut page = Page::new("?keys=m&frames=3");
//! assert_eq!(page.frames(), 0);
//! // requestAnimationFrame calls: the run stops after the URL's 3 frames.
//! let mut now = 0.0;
//! while !page.paused() {
//!     page.animation_frame(now);
//!     now += 1000.0 / 60.0;
//! }
//! assert_eq!(page.frames(), 3);
//! assert!(page.hover(0, 0).starts_with("x 0, y 0: plane 0, offset"));
//! ```

#![deny(unsafe_code)]
#![deny(missing_docs)]

pub mod hover;
pub mod keys;
pub mod lab;
pub mod pacing;
pub mod page;
pub mod slow;
pub mod url;

#[cfg(target_arch = "wasm32")]
mod exports;

#[cfg(not(target_arch = "wasm32"))]
pub mod book;
#[cfg(not(target_arch = "wasm32"))]
pub mod build;
#[cfg(not(target_arch = "wasm32"))]
pub mod serve;

/// Runs `test` on a thread with a stack of 16 MiB and passes its panic on:
/// a frame of the demo needs about 2 MiB of stack in a test build (the
/// page update's write list, the scene's page images), as much as a test
/// thread has, and the page's tests hold two machines.
#[cfg(test)]
pub(crate) fn with_big_stack(test: impl FnOnce() + Send + 'static) {
    let thread = std::thread::Builder::new()
        .stack_size(16 << 20)
        .spawn(test)
        .expect("a test thread starts");
    if let Err(panic) = thread.join() {
        std::panic::resume_unwind(panic);
    }
}

#[cfg(not(target_arch = "wasm32"))]
pub use build::{
    base64, build_page, build_page_with, build_wasm, BuildError, Built, PageFiles,
    PAGE_BUDGET_BYTES,
};
#[cfg(not(target_arch = "wasm32"))]
pub use serve::{serve, Server};
