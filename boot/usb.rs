//! Writing a disk image to a USB stick, with the checks `dd` does not make:
//! the target must be a whole disk that is removable or on USB (many USB SSDs
//! and card readers call themselves non-removable; `lsblk`'s TRAN column
//! says `usb` for them) with nothing of it in use, its description is shown,
//! and the caller must confirm before a byte is written.
//!
//! Everything is read from sysfs and procfs (Linux), under roots that tests
//! replace with a fake tree, so no test ever needs a real device.

use crate::disk_layout::{self, GptMoveError, SectorWrite, SECTOR};
use std::fs::{self, File, OpenOptions};
use std::io::{self, Read, Seek, SeekFrom, Write};
use std::os::unix::fs::{FileExt, FileTypeExt, MetadataExt};
use std::path::{Path, PathBuf};

/// sysfs counts disk sizes in 512-byte sectors, whatever the device's own.
const SYSFS_SECTOR_BYTES: u64 = 512;
const COPY_CHUNK_BYTES: usize = 4 << 20;

/// Why the image was not written, or not all of it. Every variant but
/// [`UsbError::Copy`], [`UsbError::Write`], [`UsbError::WriteGpt`] and
/// [`UsbError::Flush`] is found before a byte is written (see
/// [`UsbError::device_untouched`]).
#[derive(Debug, thiserror::Error)]
pub enum UsbError {
    /// The named device could not be looked at (it does not exist, say).
    #[error("cannot look at {}: {error}", path.display())]
    Inspect {
        /// The device as named.
        path: PathBuf,
        /// The operating system's error.
        error: io::Error,
    },
    /// The named path is a file, a directory or a character device.
    #[error(
        "{} is not a block device; name the USB stick's device, e.g. /dev/sdb \
         (see `lsblk -o NAME,SIZE,RM,TRAN,MODEL`)",
        path.display()
    )]
    NotBlockDevice {
        /// The path as named.
        path: PathBuf,
    },
    /// sysfs has no disk with the device's number.
    #[error(
        "{} (device {number}) is not a disk the kernel lists in {}",
        path.display(),
        listing.display()
    )]
    NotListed {
        /// The device as named.
        path: PathBuf,
        /// The device number, `major:minor`.
        number: String,
        /// Where sysfs lists block devices by number.
        listing: PathBuf,
    },
    /// A partition, where the image needs the whole disk.
    #[error(
        "{} is partition {partition} of disk {disk}: the image needs the whole disk, /dev/{disk}",
        path.display()
    )]
    Partition {
        /// The partition as named.
        path: PathBuf,
        /// The partition's name (`sdb1`).
        partition: String,
        /// The whole disk it belongs to (`sdb`).
        disk: String,
    },
    /// The kernel does not call the disk removable, and it is not on USB:
    /// perhaps a system disk.
    #[error(
        "{} ({name}) is not a removable disk (sysfs says removable={}) nor on USB: \
         refusing to overwrite what may be a system disk",
        path.display(),
        if removable.is_empty() { "?" } else { removable }
    )]
    NotRemovable {
        /// The device as named.
        path: PathBuf,
        /// The disk's kernel name (`sdb`).
        name: String,
        /// sysfs's `removable`, empty if it could not be read.
        removable: String,
    },
    /// sysfs gave no size for the disk.
    #[error("cannot read the size of {name} from sysfs")]
    UnknownSize {
        /// The disk's kernel name (`sdb`).
        name: String,
    },
    /// The disk's sysfs directory could not be listed.
    #[error("cannot list {}: {error}", dir.display())]
    ListSysfs {
        /// The sysfs directory.
        dir: PathBuf,
        /// The operating system's error.
        error: io::Error,
    },
    /// Part of the disk is mounted, swapped to or held by another device.
    #[error(
        "/dev/{member} is {how}: unmount every partition of /dev/{disk} first \
         (`lsblk -no MOUNTPOINTS /dev/{disk}` must print nothing)"
    )]
    InUse {
        /// The disk or partition in use (`sdb1`).
        member: String,
        /// How: "mounted on /media/stick", "used as swap", "held by dm-0".
        how: String,
        /// The whole disk it belongs to (`sdb`).
        disk: String,
    },
    /// The image could not be read.
    #[error("cannot read the image {}: {error}", path.display())]
    ReadImage {
        /// The image file.
        path: PathBuf,
        /// The operating system's error.
        error: io::Error,
    },
    /// The disk is smaller than the image.
    #[error(
        "the image ({}) does not fit on {} ({})",
        human_size(*image_bytes),
        device.display(),
        human_size(*disk_bytes)
    )]
    TooSmall {
        /// The device being written.
        device: PathBuf,
        /// The image's size.
        image_bytes: u64,
        /// The disk's size.
        disk_bytes: u64,
    },
    /// The image's GPT is not one that can be moved to the disk's end.
    #[error("cannot move the GPT of {} to the disk's end: {error}", image.display())]
    Gpt {
        /// The image.
        image: PathBuf,
        /// What is wrong with its GPT.
        error: GptMoveError,
    },
    /// The user did not confirm.
    #[error("not confirmed: nothing was written to {}", device.display())]
    NotConfirmed {
        /// The device being written.
        device: PathBuf,
    },
    /// The device could not be opened for writing (permissions, usually).
    #[error("cannot open {} for writing: {error}", device.display())]
    OpenDevice {
        /// The device being written.
        device: PathBuf,
        /// The operating system's error.
        error: io::Error,
    },
    /// Reading the image failed during the copy: the device may hold part of it.
    #[error(
        "reading {} failed after {written} bytes were written to {}: {error}",
        image.display(),
        device.display()
    )]
    Copy {
        /// The image being copied.
        image: PathBuf,
        /// The device being written.
        device: PathBuf,
        /// Bytes written before the failure.
        written: u64,
        /// The operating system's error.
        error: io::Error,
    },
    /// Writing failed part of the way: the device holds part of the image.
    #[error("writing {} failed after {written} bytes: {error}", device.display())]
    Write {
        /// The device being written.
        device: PathBuf,
        /// Bytes written before the failure.
        written: u64,
        /// The operating system's error.
        error: io::Error,
    },
    /// The image was written, but moving its backup GPT to the disk's end
    /// failed: the disk's GPT may be half moved.
    #[error(
        "the image was written, but writing the GPT's sectors at LBA {lba} of {} failed: \
         {error}; run `sudo sgdisk -e {}` or write the stick again",
        device.display(),
        device.display()
    )]
    WriteGpt {
        /// The device being written.
        device: PathBuf,
        /// The first sector of the write that failed.
        lba: u64,
        /// The operating system's error.
        error: io::Error,
    },
    /// Everything was written but the device did not confirm it has it.
    #[error("flushing {} failed: {error}", device.display())]
    Flush {
        /// The device being written.
        device: PathBuf,
        /// The operating system's error.
        error: io::Error,
    },
}

impl UsbError {
    /// Whether the device is as it was: true of every refusal, false once
    /// writing has begun.
    pub fn device_untouched(&self) -> bool {
        !matches!(
            self,
            UsbError::Copy { .. }
                | UsbError::Write { .. }
                | UsbError::WriteGpt { .. }
                | UsbError::Flush { .. }
        )
    }
}

/// What [`write_image_to_usb`] wrote, all flushed to the device.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Written {
    /// The image's bytes, written from the device's start.
    pub bytes: u64,
    /// Where the backup GPT header now is (the disk's last sector), when the
    /// image has a GPT and the disk is larger than the image.
    pub backup_gpt_lba: Option<u64>,
}

/// Writes `image` to the whole removable or USB disk `device` (e.g. `/dev/sdb`)
/// after checking it and calling `confirm` with a description of what will
/// be overwritten; returns what was written, flushed to the device.
///
/// An image with a GPT has its backup GPT moved to the disk's end afterwards,
/// as `sgdisk -e` would (`disk_layout::backup_gpt_to_disk_end`): firmware
/// looks for it in the disk's last sector, not the image's.
///
/// Refused, with an error saying why: anything that is not a block device,
/// a partition rather than a whole disk, a disk the kernel neither reports as
/// removable nor finds on a USB bus, a disk with a partition mounted, used as swap or held by
/// device-mapper, RAID or LVM, a disk smaller than the image, and an answer
/// of `false` from `confirm` (nothing is written then).
pub fn write_image_to_usb(
    image: &Path,
    device: &Path,
    confirm: impl FnOnce(&str) -> bool,
) -> Result<Written, UsbError> {
    let node = DeviceNode::inspect(device)?;
    write_checked(image, &node, &SystemRoots::live(), confirm)
}

/// Where sysfs and procfs are: `/sys` and `/proc`, or a test's fake tree.
struct SystemRoots {
    sys: PathBuf,
    proc: PathBuf,
}

impl SystemRoots {
    fn live() -> Self {
        SystemRoots {
            sys: PathBuf::from("/sys"),
            proc: PathBuf::from("/proc"),
        }
    }
}

/// A block device special file and the device number it stands for.
#[derive(Clone, Debug)]
struct DeviceNode {
    path: PathBuf,
    /// "major:minor", as sysfs and mountinfo write it.
    number: String,
}

impl DeviceNode {
    fn inspect(path: &Path) -> Result<Self, UsbError> {
        let metadata = fs::metadata(path).map_err(|error| UsbError::Inspect {
            path: path.to_owned(),
            error,
        })?;
        if !metadata.file_type().is_block_device() {
            return Err(UsbError::NotBlockDevice {
                path: path.to_owned(),
            });
        }
        Ok(DeviceNode {
            path: path.to_owned(),
            number: device_number(metadata.rdev()),
        })
    }
}

/// Linux's encoding of a dev_t as "major:minor".
fn device_number(rdev: u64) -> String {
    let major = ((rdev >> 8) & 0xFFF) | ((rdev >> 32) & !0xFFF);
    let minor = (rdev & 0xFF) | ((rdev >> 12) & !0xFF);
    format!("{major}:{minor}")
}

/// A whole disk as sysfs describes it.
struct Disk {
    name: String,
    /// The disk's sysfs directory (`/sys/devices/.../block/sdb`).
    dir: PathBuf,
    /// The device numbers of the disk and each of its partitions, with names.
    members: Vec<(String, String)>,
    bytes: u64,
    /// sysfs's `removable` is 1 (else the disk is on USB).
    removable: bool,
}

/// Whether the disk whose sysfs directory is `dir` hangs off a USB bus: its
/// device path runs through a USB bus (`.../usb2/2-1/...`), the test `lsblk`
/// makes for its TRAN column's `usb`.
fn on_usb(dir: &Path) -> bool {
    dir.components().any(|part| {
        part.as_os_str()
            .to_str()
            .and_then(|name| name.strip_prefix("usb"))
            .is_some_and(|bus| !bus.is_empty() && bus.bytes().all(|b| b.is_ascii_digit()))
    })
}

impl Disk {
    /// The whole, removable or USB disk behind `node`, or why not.
    fn identify(node: &DeviceNode, roots: &SystemRoots) -> Result<Disk, UsbError> {
        let listing = roots.sys.join("dev/block");
        let Ok(dir) = fs::canonicalize(listing.join(&node.number)) else {
            return Err(UsbError::NotListed {
                path: node.path.clone(),
                number: node.number.clone(),
                listing,
            });
        };
        let name = file_name(&dir);
        if dir.join("partition").exists() {
            return Err(UsbError::Partition {
                path: node.path.clone(),
                disk: dir.parent().map(file_name).unwrap_or_default(),
                partition: name,
            });
        }
        let removable = read_trimmed(&dir.join("removable")).unwrap_or_default();
        if removable != "1" && !on_usb(&dir) {
            return Err(UsbError::NotRemovable {
                path: node.path.clone(),
                name,
                removable,
            });
        }
        let Some(sectors) = read_trimmed(&dir.join("size")).and_then(|s| s.parse::<u64>().ok())
        else {
            return Err(UsbError::UnknownSize { name });
        };
        let mut members = vec![(name.clone(), node.number.clone())];
        let list_error = |error| UsbError::ListSysfs {
            dir: dir.clone(),
            error,
        };
        for entry in fs::read_dir(&dir).map_err(list_error)? {
            let partition = entry.map_err(list_error)?.path();
            if partition.join("partition").exists() {
                if let Some(number) = read_trimmed(&partition.join("dev")) {
                    members.push((file_name(&partition), number));
                }
            }
        }
        Ok(Disk {
            name,
            dir,
            members,
            bytes: sectors * SYSFS_SECTOR_BYTES,
            removable: removable == "1",
        })
    }

    /// Refuses a disk any part of which is mounted, swapped to, or held by
    /// another block device (device-mapper, RAID, LVM).
    fn ensure_unused(&self, roots: &SystemRoots) -> Result<(), UsbError> {
        // mountinfo's third field is the mounted filesystem's device number,
        // whatever name the mount was made by (/dev/disk/by-uuid/..., /dev/root).
        let mountinfo = fs::read_to_string(roots.proc.join("self/mountinfo")).unwrap_or_default();
        for line in mountinfo.lines() {
            let fields: Vec<&str> = line.split_whitespace().collect();
            if let (Some(number), Some(mount_point)) = (fields.get(2), fields.get(4)) {
                if let Some((member, _)) = self.members.iter().find(|(_, n)| n == number) {
                    return Err(self.in_use(member, format!("mounted on {mount_point}")));
                }
            }
        }
        // /proc/mounts and /proc/swaps name the device the way it was mounted.
        for (table, how) in [("mounts", "mounted on"), ("swaps", "used as swap")] {
            let text = fs::read_to_string(roots.proc.join(table)).unwrap_or_default();
            for line in text.lines() {
                let mut fields = line.split_whitespace();
                // Pseudo filesystems ("proc", "tmpfs") name no device.
                let (Some(source), rest) = (fields.next(), fields.next()) else {
                    continue;
                };
                if !source.starts_with('/') {
                    continue;
                }
                let source = fs::canonicalize(source).unwrap_or_else(|_| PathBuf::from(source));
                let source_name = file_name(&source);
                if let Some((member, _)) = self.members.iter().find(|(m, _)| *m == source_name) {
                    let what = match table {
                        "mounts" => format!("{how} {}", rest.unwrap_or("?")),
                        _ => how.to_owned(),
                    };
                    return Err(self.in_use(member, what));
                }
            }
        }
        for (member, _) in &self.members {
            let holders = if *member == self.name {
                self.dir.join("holders")
            } else {
                self.dir.join(member).join("holders")
            };
            if let Some(holder) = fs::read_dir(holders).ok().and_then(|mut d| d.next()) {
                let holder = holder.map(|h| file_name(&h.path())).unwrap_or_default();
                return Err(self.in_use(member, format!("held by {holder}")));
            }
        }
        Ok(())
    }

    fn in_use(&self, member: &str, how: String) -> UsbError {
        UsbError::InUse {
            member: member.to_owned(),
            how,
            disk: self.name.clone(),
        }
    }

    /// What will be overwritten, for the confirmation.
    fn describe(&self, node: &DeviceNode, image: &Path, image_bytes: u64) -> String {
        let field = |name: &str| read_trimmed(&self.dir.join("device").join(name));
        let maker: Vec<String> = [field("vendor"), field("model")]
            .into_iter()
            .flatten()
            .filter(|s| !s.is_empty())
            .collect();
        let maker = if maker.is_empty() {
            "unknown make".to_owned()
        } else {
            maker.join(" ")
        };
        let kind = if self.removable {
            "removable"
        } else {
            "a USB disk that says it is not removable"
        };
        format!(
            "{} ({}) will be overwritten with {} ({}): {maker}, {}, {kind}. \
             Everything on it will be lost.",
            node.path.display(),
            self.name,
            image.display(),
            human_size(image_bytes),
            human_size(self.bytes),
        )
    }
}

/// All checks, the confirmation, then the copy.
fn write_checked(
    image: &Path,
    node: &DeviceNode,
    roots: &SystemRoots,
    confirm: impl FnOnce(&str) -> bool,
) -> Result<Written, UsbError> {
    let disk = Disk::identify(node, roots)?;
    disk.ensure_unused(roots)?;
    let image_bytes = fs::metadata(image)
        .map_err(|error| UsbError::ReadImage {
            path: image.to_owned(),
            error,
        })?
        .len();
    if image_bytes > disk.bytes {
        return Err(UsbError::TooSmall {
            device: node.path.clone(),
            image_bytes,
            disk_bytes: disk.bytes,
        });
    }
    // Planned before the question, so that an image whose GPT cannot be
    // moved is refused with nothing written.
    let gpt_writes = plan_gpt_move(image, image_bytes, disk.bytes)?;
    if !confirm(&disk.describe(node, image, image_bytes)) {
        return Err(UsbError::NotConfirmed {
            device: node.path.clone(),
        });
    }
    let bytes = copy_and_sync(image, &node.path, gpt_writes.as_deref().unwrap_or_default())?;
    Ok(Written {
        bytes,
        backup_gpt_lba: gpt_writes
            .filter(|writes| !writes.is_empty())
            .map(|_| disk.bytes / SECTOR as u64 - 1),
    })
}

/// The sectors that move the image's backup GPT to the end of a disk of
/// `disk_bytes`; `None` for an image without a GPT.
fn plan_gpt_move(
    image: &Path,
    image_bytes: u64,
    disk_bytes: u64,
) -> Result<Option<Vec<SectorWrite>>, UsbError> {
    let sector = SECTOR as u64;
    if !image_bytes.is_multiple_of(sector) || image_bytes < disk_layout::GPT_HEAD_SECTORS * sector {
        return Ok(None);
    }
    let read_error = |error| UsbError::ReadImage {
        path: image.to_owned(),
        error,
    };
    let mut file = File::open(image).map_err(read_error)?;
    let mut head = vec![0; disk_layout::GPT_HEAD_SECTORS as usize * SECTOR];
    file.read_exact(&mut head).map_err(read_error)?;
    let mut last = vec![0; SECTOR];
    file.seek(SeekFrom::Start(image_bytes - sector))
        .and_then(|_| file.read_exact(&mut last))
        .map_err(read_error)?;
    disk_layout::backup_gpt_to_disk_end(&head, &last, image_bytes / sector, disk_bytes / sector)
        .map_err(|error| UsbError::Gpt {
            image: image.to_owned(),
            error,
        })
}

/// Copies `image` to the start of `device`, then makes `gpt_writes`, and
/// waits until the device has it all.
fn copy_and_sync(image: &Path, device: &Path, gpt_writes: &[SectorWrite]) -> Result<u64, UsbError> {
    let mut source = File::open(image).map_err(|error| UsbError::ReadImage {
        path: image.to_owned(),
        error,
    })?;
    // No create, no truncate: the device must exist, and a block device has
    // no length to cut.
    let mut target = OpenOptions::new()
        .write(true)
        .open(device)
        .map_err(|error| UsbError::OpenDevice {
            device: device.to_owned(),
            error,
        })?;
    let mut chunk = vec![0; COPY_CHUNK_BYTES];
    let mut written = 0u64;
    loop {
        let read = source.read(&mut chunk).map_err(|error| UsbError::Copy {
            image: image.to_owned(),
            device: device.to_owned(),
            written,
            error,
        })?;
        if read == 0 {
            break;
        }
        target
            .write_all(&chunk[..read])
            .map_err(|error| UsbError::Write {
                device: device.to_owned(),
                written,
                error,
            })?;
        written += read as u64;
    }
    for write in gpt_writes {
        target
            .write_all_at(&write.bytes, write.lba * SECTOR as u64)
            .map_err(|error| UsbError::WriteGpt {
                device: device.to_owned(),
                lba: write.lba,
                error,
            })?;
    }
    target.sync_all().map_err(|error| UsbError::Flush {
        device: device.to_owned(),
        error,
    })?;
    Ok(written)
}

fn read_trimmed(path: &Path) -> Option<String> {
    fs::read_to_string(path).ok().map(|s| s.trim().to_owned())
}

fn file_name(path: &Path) -> String {
    path.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// "15.6 GB (15631122432 bytes)": decimal units, as sticks are sold.
fn human_size(bytes: u64) -> String {
    let units = [("GB", 1e9), ("MB", 1e6), ("kB", 1e3)];
    let (unit, size) = units
        .iter()
        .find(|(_, size)| bytes as f64 >= *size)
        .unwrap_or(&("bytes", 1.0));
    if *unit == "bytes" {
        format!("{bytes} bytes")
    } else {
        format!("{:.1} {unit} ({bytes} bytes)", bytes as f64 / size)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::os::unix::fs::symlink;
    use std::sync::atomic::{AtomicU32, Ordering};

    /// A fake /sys and /proc with one disk, `sdb` (8:16), partition `sdb1`
    /// (8:17), a 16 MiB "device" that is a plain file, and a 1 MiB image.
    /// [`Fixture::new`]'s disk is on USB; [`Fixture::on_bus`] puts it elsewhere.
    struct Fixture {
        root: PathBuf,
        roots: SystemRoots,
        node: DeviceNode,
        image: PathBuf,
    }

    const DEVICE_BYTES: u64 = 16 << 20;
    /// Where a USB stick sits in sysfs: below a USB bus.
    const USB_BUS: &str = "0000:00:14.0/usb2/2-1/2-1:1.0/host6/target6:0:0/6:0:0:0";
    /// Where a SATA disk sits in sysfs.
    const SATA_BUS: &str = "0000:00:17.0/ata1/host0/target0:0:0/0:0:0:0";
    const ORIGINAL: u8 = 0xEE;

    impl Fixture {
        fn new(removable: &str) -> Fixture {
            Fixture::on_bus(USB_BUS, removable)
        }

        fn on_bus(bus: &str, removable: &str) -> Fixture {
            static NEXT: AtomicU32 = AtomicU32::new(0);
            let root = std::env::temp_dir().join(format!(
                "modex-usb-test-{}-{}",
                std::process::id(),
                NEXT.fetch_add(1, Ordering::Relaxed)
            ));
            let disk = root
                .join("sys/devices/pci0000:00")
                .join(bus)
                .join("block/sdb");
            fs::create_dir_all(disk.join("sdb1")).unwrap();
            fs::create_dir_all(disk.join("device")).unwrap();
            fs::create_dir_all(disk.join("holders")).unwrap();
            fs::create_dir_all(disk.join("sdb1/holders")).unwrap();
            fs::create_dir_all(root.join("sys/dev/block")).unwrap();
            fs::create_dir_all(root.join("proc/self")).unwrap();
            let write = |path: PathBuf, text: &str| fs::write(path, text).unwrap();
            write(disk.join("removable"), &format!("{removable}\n"));
            write(disk.join("size"), &format!("{}\n", DEVICE_BYTES / 512));
            write(disk.join("dev"), "8:16\n");
            write(disk.join("device/vendor"), "SanDisk \n");
            write(disk.join("device/model"), "Cruzer Blade    \n");
            write(disk.join("sdb1/partition"), "1\n");
            write(disk.join("sdb1/dev"), "8:17\n");
            symlink(&disk, root.join("sys/dev/block/8:16")).unwrap();
            symlink(disk.join("sdb1"), root.join("sys/dev/block/8:17")).unwrap();
            write(
                root.join("proc/mounts"),
                "/dev/vda1 / ext4 rw,relatime 0 0\nproc /proc proc rw 0 0\n",
            );
            write(
                root.join("proc/self/mountinfo"),
                "22 1 254:1 / / rw,relatime shared:1 - ext4 /dev/vda1 rw\n",
            );
            write(
                root.join("proc/swaps"),
                "Filename Type Size Used Priority\n",
            );
            let device = root.join("sdb-contents");
            fs::write(&device, vec![ORIGINAL; DEVICE_BYTES as usize]).unwrap();
            let image = root.join("bios.img");
            fs::write(&image, (0..1 << 20).map(|i| i as u8).collect::<Vec<u8>>()).unwrap();
            Fixture {
                roots: SystemRoots {
                    sys: root.join("sys"),
                    proc: root.join("proc"),
                },
                node: DeviceNode {
                    path: device,
                    number: "8:16".into(),
                },
                image,
                root,
            }
        }

        /// [`Fixture::new`]'s removable disk on USB, with this image and a
        /// device of `device_bytes` (all [`ORIGINAL`]).
        fn sized(image: &[u8], device_bytes: u64) -> Fixture {
            let fixture = Fixture::new("1");
            fs::write(&fixture.image, image).unwrap();
            fs::write(&fixture.node.path, vec![ORIGINAL; device_bytes as usize]).unwrap();
            let size = format!("{}\n", device_bytes / SYSFS_SECTOR_BYTES);
            fs::write(fixture.usb_disk().join("size"), size).unwrap();
            fixture
        }

        /// The disk's sysfs directory, for [`Fixture::new`]'s disk on USB.
        fn usb_disk(&self) -> PathBuf {
            self.roots
                .sys
                .join("devices/pci0000:00")
                .join(USB_BUS)
                .join("block/sdb")
        }

        fn write(&self, confirm: impl FnOnce(&str) -> bool) -> Result<Written, UsbError> {
            write_checked(&self.image, &self.node, &self.roots, confirm)
        }

        fn device_untouched(&self) -> bool {
            fs::read(&self.node.path)
                .unwrap()
                .iter()
                .all(|&b| b == ORIGINAL)
        }

        fn append(&self, file: &str, line: &str) {
            let path = self.root.join("proc").join(file);
            let text = fs::read_to_string(&path).unwrap() + line;
            fs::write(path, text).unwrap();
        }
    }

    impl Drop for Fixture {
        fn drop(&mut self) {
            let _ = fs::remove_dir_all(&self.root);
        }
    }

    /// The refusal, which must come before the question, with nothing written.
    fn refused(fixture: &Fixture) -> UsbError {
        let mut asked = false;
        let error = fixture
            .write(|_| {
                asked = true;
                true
            })
            .expect_err("must be refused");
        assert!(!asked, "refused only after asking: {error}");
        assert!(fixture.device_untouched(), "written although refused");
        assert!(
            error.device_untouched(),
            "{error:?} says the device was written"
        );
        error
    }

    /// Writes with the confirmation given; returns what it showed, after
    /// checking that the whole image was written.
    fn confirmed_write(fixture: &Fixture) -> String {
        let mut shown = String::new();
        let written = fixture
            .write(|description| {
                shown = description.to_owned();
                true
            })
            .unwrap();
        assert_eq!(written.bytes, 1 << 20);
        assert_eq!(written.backup_gpt_lba, None, "the test image has no GPT");
        let device = fs::read(&fixture.node.path).unwrap();
        assert_eq!(device[..1 << 20], fs::read(&fixture.image).unwrap()[..]);
        shown
    }

    #[test]
    fn a_removable_unmounted_disk_is_described_then_written_and_synced() {
        let fixture = Fixture::new("1");
        let shown = confirmed_write(&fixture);
        for part in [
            "sdb",
            "SanDisk Cruzer Blade",
            "16.8 MB (16777216 bytes)",
            "removable",
        ] {
            assert!(shown.contains(part), "{part:?} missing from {shown:?}");
        }
        let device = fs::read(&fixture.node.path).unwrap();
        assert!(device[1 << 20..].iter().all(|&b| b == ORIGINAL));
    }

    /// `--write-usb`'s image on a stick 64 MiB larger than it: read back
    /// with the `gpt` crate, both headers are valid and at the stick's real
    /// end, as after `sgdisk -e`; the MBR is the image's, with its one
    /// active entry; everything else of the image is as it was.
    #[test]
    fn the_one_images_backup_gpt_is_moved_to_the_end_of_a_larger_stick() {
        let image = fs::read(env!("ONE_IMAGE")).unwrap();
        let image_bytes = image.len() as u64;
        let device_bytes = image_bytes + (64 << 20);
        let fixture = Fixture::sized(&image, device_bytes);
        let written = fixture.write(|_| true).unwrap();
        let last = device_bytes / 512 - 1;
        assert_eq!(
            written,
            Written {
                bytes: image_bytes,
                backup_gpt_lba: Some(last)
            }
        );

        let disk = fs::read(&fixture.node.path).unwrap();
        assert_eq!(disk.len() as u64, device_bytes);
        let gpt = gpt::GptConfig::new()
            .writable(false)
            .open(&fixture.node.path)
            .unwrap_or_else(|e| panic!("the gpt crate cannot read the stick: {e}"));
        let primary = gpt.primary_header().expect("primary header");
        let backup = gpt.backup_header().expect("backup header");
        assert_eq!((primary.current_lba, primary.backup_lba), (1, last));
        assert_eq!((backup.current_lba, backup.backup_lba), (last, 1));
        let entry_sectors = disk_layout::GPT_ENTRY_SECTORS;
        assert_eq!(
            (primary.part_start, backup.part_start),
            (2, last - entry_sectors)
        );
        for header in [primary, backup] {
            assert_eq!(header.last_usable, last - entry_sectors - 1, "{header:?}");
            let table = &disk[header.part_start as usize * SECTOR..]
                [..(header.num_parts * header.part_size) as usize];
            assert_eq!(crc32fast::hash(table), header.crc32_parts, "{header:?}");
        }
        assert_eq!(&disk[last as usize * SECTOR..][..8], b"EFI PART");
        assert_eq!(gpt.partitions().len(), 2);

        // The MBR is the image's: one active entry, stage 2's.
        assert_eq!(disk[..SECTOR], image[..SECTOR]);
        let active = (0..4).filter(|i| disk[446 + 16 * i] == 0x80).count();
        assert_eq!(active, 1, "active MBR entries");
        // The old backup header is zeros; the rest of the image is as written.
        let old_backup = image.len() - SECTOR;
        assert!(disk[old_backup..image.len()].iter().all(|&b| b == 0));
        assert_eq!(disk[2 * SECTOR..old_backup], image[2 * SECTOR..old_backup]);
        // Between the image and the new entries, the stick is untouched.
        let new_entries = (last - entry_sectors) as usize * SECTOR;
        assert!(disk[image.len()..new_entries]
            .iter()
            .all(|&b| b == ORIGINAL));
    }

    #[test]
    fn an_image_whose_gpt_is_broken_is_refused_before_anything_is_written() {
        let mut image = fs::read(env!("ONE_IMAGE")).unwrap();
        image[SECTOR + 40] ^= 1; // the primary header's first usable LBA
        let fixture = Fixture::sized(&image, image.len() as u64 + (1 << 20));
        let error = refused(&fixture);
        assert!(matches!(error, UsbError::Gpt { .. }), "{error:?}");
        assert!(error.to_string().contains("wrong CRC"), "{error}");
    }

    #[test]
    fn declining_the_confirmation_writes_nothing() {
        let fixture = Fixture::new("1");
        let error = fixture.write(|_| false).unwrap_err();
        assert!(matches!(error, UsbError::NotConfirmed { .. }), "{error:?}");
        assert!(error.to_string().contains("nothing was written"), "{error}");
        assert!(fixture.device_untouched());
    }

    #[test]
    fn a_fixed_disk_is_refused() {
        let error = refused(&Fixture::on_bus(SATA_BUS, "0"));
        assert!(
            matches!(&error, UsbError::NotRemovable { removable, .. } if removable == "0"),
            "{error:?}"
        );
        let error = error.to_string();
        assert!(error.contains("not a removable disk"), "{error}");
        assert!(error.contains("removable=0"), "{error}");
    }

    /// Many USB SSDs and card readers report removable=0; on a USB bus they
    /// are written after the same confirmation, which says what they are.
    #[test]
    fn a_non_removable_usb_disk_is_described_then_written() {
        let shown = confirmed_write(&Fixture::new("0"));
        assert!(
            shown.contains("a USB disk that says it is not removable"),
            "{shown:?}"
        );
    }

    /// A removable disk off USB (an SD slot on PCI) is still accepted.
    #[test]
    fn a_removable_disk_not_on_usb_is_accepted() {
        let fixture = Fixture::on_bus("0000:00:1e.6/mmc_host/mmc0/mmc0:0001", "1");
        assert_eq!(fixture.write(|_| true).unwrap().bytes, 1 << 20);
    }

    #[test]
    fn usb_is_told_by_a_usb_bus_in_the_device_path() {
        let sys = Path::new("/sys/devices/pci0000:00");
        assert!(on_usb(&sys.join(USB_BUS).join("block/sdb")));
        assert!(!on_usb(&sys.join(SATA_BUS).join("block/sda")));
        // Not a bus: a name that merely starts with "usb".
        assert!(!on_usb(&sys.join("0000:00:17.0/usbfoo/block/sdc")));
        assert!(!on_usb(&sys.join("nvme/usb/block/nvme0n1")));
    }

    #[test]
    fn a_partition_is_refused_with_the_whole_disk_named() {
        let mut fixture = Fixture::new("1");
        fixture.node.number = "8:17".into();
        let error = refused(&fixture);
        assert!(
            matches!(&error, UsbError::Partition { disk, .. } if disk == "sdb"),
            "{error:?}"
        );
        let error = error.to_string();
        assert!(error.contains("partition sdb1 of disk sdb"), "{error}");
        assert!(error.contains("/dev/sdb"), "{error}");
    }

    #[test]
    fn a_disk_with_a_mounted_partition_is_refused() {
        let fixture = Fixture::new("1");
        fixture.append("mounts", "/dev/sdb1 /media/stick vfat rw 0 0\n");
        let error = refused(&fixture);
        assert!(
            matches!(&error, UsbError::InUse { member, .. } if member == "sdb1"),
            "{error:?}"
        );
        let error = error.to_string();
        assert!(
            error.contains("/dev/sdb1 is mounted on /media/stick"),
            "{error}"
        );
    }

    #[test]
    fn a_mount_made_by_another_name_is_found_by_device_number() {
        let fixture = Fixture::new("1");
        fixture.append(
            "self/mountinfo",
            "40 22 8:17 / /media/stick rw - vfat /dev/disk/by-label/STICK rw\n",
        );
        let error = refused(&fixture).to_string();
        assert!(
            error.contains("/dev/sdb1 is mounted on /media/stick"),
            "{error}"
        );
    }

    #[test]
    fn a_mounted_whole_disk_is_refused() {
        let fixture = Fixture::new("1");
        fixture.append(
            "self/mountinfo",
            "40 22 8:16 / /mnt rw - iso9660 /dev/sdb ro\n",
        );
        let error = refused(&fixture).to_string();
        assert!(error.contains("/dev/sdb is mounted on /mnt"), "{error}");
    }

    #[test]
    fn a_partition_used_as_swap_or_held_by_device_mapper_is_refused() {
        let fixture = Fixture::new("1");
        fixture.append("swaps", "/dev/sdb1 partition 1024 0 -2\n");
        let error = refused(&fixture).to_string();
        assert!(error.contains("used as swap"), "{error}");

        let fixture = Fixture::new("1");
        let holder = fixture.usb_disk().join("sdb1/holders/dm-0");
        fs::create_dir_all(holder).unwrap();
        let error = refused(&fixture).to_string();
        assert!(error.contains("held by dm-0"), "{error}");
    }

    #[test]
    fn an_image_larger_than_the_disk_is_refused() {
        let fixture = Fixture::new("1");
        let sectors = fixture.usb_disk().join("size");
        fs::write(sectors, "1024\n").unwrap(); // 512 KiB
        let error = refused(&fixture);
        assert!(matches!(error, UsbError::TooSmall { .. }), "{error:?}");
        assert!(error.to_string().contains("does not fit"), "{error}");
    }

    #[test]
    fn a_device_sysfs_does_not_list_is_refused() {
        let mut fixture = Fixture::new("1");
        fixture.node.number = "8:32".into();
        let error = refused(&fixture);
        assert!(matches!(error, UsbError::NotListed { .. }), "{error:?}");
        let error = error.to_string();
        assert!(error.contains("not a disk the kernel lists"), "{error}");
    }

    #[test]
    fn what_is_not_a_block_device_is_refused_before_anything_else() {
        let fixture = Fixture::new("1");
        for path in [
            fixture.image.as_path(),
            Path::new("/dev/null"),
            Path::new("/"),
        ] {
            let error = write_image_to_usb(&fixture.image, path, |_| panic!("asked")).unwrap_err();
            assert!(
                matches!(error, UsbError::NotBlockDevice { .. }),
                "{error:?}"
            );
            assert!(
                error.to_string().contains("is not a block device"),
                "{error}"
            );
        }
        let error = write_image_to_usb(&fixture.image, &fixture.root.join("missing"), |_| {
            panic!("asked")
        })
        .unwrap_err();
        assert!(matches!(error, UsbError::Inspect { .. }), "{error:?}");
        assert!(error.to_string().contains("cannot look at"), "{error}");
    }

    #[test]
    fn device_numbers_decode_as_linux_encodes_them() {
        assert_eq!(device_number(0x0810), "8:16");
        assert_eq!(device_number(0x0811), "8:17");
        // Minor 0x12345 needs the split encoding (high minor bits above the major).
        let rdev = (259u64 & 0xFFF) << 8 | (0x12345u64 & 0xFF) | (0x12345u64 & !0xFF) << 12;
        assert_eq!(device_number(rdev), "259:74565");
    }
}
