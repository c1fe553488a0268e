//! The disk images the build script made, copied to stable paths a user can
//! find and write to a USB stick: `target/images/modex-cube.img`, the one image
//! that boots under BIOS (and CSM) and under UEFI, and the single-firmware
//! `bios.img` and `uefi.img`.

use std::io;
use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};

/// Built by `boot/build.rs` into cargo's OUT_DIR.
const BUILT_HYBRID_IMAGE: &str = env!("ONE_IMAGE");
/// Built by `boot/build.rs` into cargo's OUT_DIR.
const BUILT_BIOS_IMAGE: &str = env!("BIOS_IMAGE");
/// Built by `boot/build.rs` into cargo's OUT_DIR.
const BUILT_UEFI_IMAGE: &str = env!("UEFI_IMAGE");

/// Where the published images are: stable paths that survive rebuilds.
#[derive(Clone, Debug)]
pub struct Images {
    /// The one image for every PC: a GPT disk with a hybrid MBR, booting
    /// under BIOS (and CSM) and under UEFI from the same bytes.
    pub hybrid: PathBuf,
    /// The legacy-BIOS disk image (MBR boot sector and stage loaders).
    pub bios: PathBuf,
    /// The UEFI disk image (GPT with an EFI system partition).
    pub uefi: PathBuf,
}

/// `$CARGO_TARGET_DIR/images`, or `target/images` in the workspace.
pub fn images_dir() -> PathBuf {
    let target = std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("target"));
    target.join("images")
}

/// Why the images could not be published. Cloned, because every caller of
/// [`publish`] in a process gets the one outcome; the I/O error is shared.
#[derive(Clone, Debug, thiserror::Error)]
pub enum PublishError {
    /// The build script's image is not there: the build did not finish.
    #[error("cannot read the built image {}: {error}", path.display())]
    ReadBuilt {
        /// The image in cargo's OUT_DIR.
        path: PathBuf,
        /// Why it could not be read.
        error: Arc<io::Error>,
    },
    /// The stable path's directory, or a file in it, could not be written.
    #[error("cannot {action} {}: {error}", path.display())]
    Write {
        /// "create", "write" or "rename to".
        action: &'static str,
        /// The directory or file acted on.
        path: PathBuf,
        /// Why the action failed.
        error: Arc<io::Error>,
    },
}

impl PublishError {
    fn write(action: &'static str, path: &Path) -> impl FnOnce(io::Error) -> Self {
        let path = path.to_owned();
        move |error| PublishError::Write {
            action,
            path,
            error: Arc::new(error),
        }
    }
}

/// Copies the freshly built images to their stable paths, once per process
/// (tests call this from many threads at once).
pub fn publish() -> Result<Images, PublishError> {
    static PUBLISHED: OnceLock<Result<Images, PublishError>> = OnceLock::new();
    PUBLISHED.get_or_init(publish_now).clone()
}

fn publish_now() -> Result<Images, PublishError> {
    let dir = images_dir();
    std::fs::create_dir_all(&dir).map_err(PublishError::write("create", &dir))?;
    let images = Images {
        hybrid: dir.join("modex-cube.img"),
        bios: dir.join("bios.img"),
        uefi: dir.join("uefi.img"),
    };
    copy_if_changed(Path::new(BUILT_HYBRID_IMAGE), &images.hybrid)?;
    copy_if_changed(Path::new(BUILT_BIOS_IMAGE), &images.bios)?;
    copy_if_changed(Path::new(BUILT_UEFI_IMAGE), &images.uefi)?;
    Ok(images)
}

fn copy_if_changed(from: &Path, to: &Path) -> Result<(), PublishError> {
    let fresh = std::fs::read(from).map_err(|error| PublishError::ReadBuilt {
        path: from.to_owned(),
        error: Arc::new(error),
    })?;
    if std::fs::read(to).is_ok_and(|old| old == fresh) {
        return Ok(());
    }
    // Write then rename, so a concurrent reader (another test process) never
    // sees half an image.
    let partial = to.with_extension(format!("img.{}", std::process::id()));
    std::fs::write(&partial, &fresh).map_err(PublishError::write("write", &partial))?;
    std::fs::rename(&partial, to).map_err(PublishError::write("rename to", to))
}
