//! The disk images the build script made, copied to stable paths a user can
//! find and write to a USB stick: `target/images/bios.img` and `uefi.img`.

use std::path::{Path, PathBuf};

/// Built by `boot/build.rs` into cargo's OUT_DIR.
const BUILT_BIOS_IMAGE: &str = env!("BIOS_IMAGE");
const BUILT_UEFI_IMAGE: &str = env!("UEFI_IMAGE");

#[derive(Clone, Debug)]
pub struct Images {
    pub bios: PathBuf,
    pub uefi: PathBuf,
}

/// `$CARGO_TARGET_DIR/images`, or `target/images` in the workspace.
pub fn images_dir() -> PathBuf {
    let target = std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("target"));
    target.join("images")
}

/// Copies the freshly built images to their stable paths, once per process
/// (tests call this from many threads at once).
pub fn publish() -> Result<Images, String> {
    static PUBLISHED: std::sync::OnceLock<Result<Images, String>> = std::sync::OnceLock::new();
    PUBLISHED.get_or_init(publish_now).clone()
}

fn publish_now() -> Result<Images, String> {
    let dir = images_dir();
    std::fs::create_dir_all(&dir).map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
    let images = Images {
        bios: dir.join("bios.img"),
        uefi: dir.join("uefi.img"),
    };
    copy_if_changed(Path::new(BUILT_BIOS_IMAGE), &images.bios)?;
    copy_if_changed(Path::new(BUILT_UEFI_IMAGE), &images.uefi)?;
    Ok(images)
}

fn copy_if_changed(from: &Path, to: &Path) -> Result<(), String> {
    let fresh = std::fs::read(from)
        .map_err(|e| format!("cannot read the built image {}: {e}", from.display()))?;
    if std::fs::read(to).is_ok_and(|old| old == fresh) {
        return Ok(());
    }
    // Write then rename, so a concurrent reader (another test process) never
    // sees half an image.
    let partial = to.with_extension(format!("img.{}", std::process::id()));
    std::fs::write(&partial, &fresh)
        .map_err(|e| format!("cannot write {}: {e}", partial.display()))?;
    std::fs::rename(&partial, to).map_err(|e| format!("cannot rename to {}: {e}", to.display()))
}
