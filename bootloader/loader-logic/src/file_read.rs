//! Reading a file from the boot volume through the firmware's file protocol
//! (CHANGES.md, issue 38): every call's status is checked, a read that fails
//! is tried once more, and a failure that stays is told in words that name
//! the file, the step, the firmware's status and what to try.
//!
//! The loader makes the firmware calls; this module holds the policy and the
//! words, so that both are tested on the host.

use core::fmt;

/// The firmware call of a file read that failed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Step {
    /// `EFI_SIMPLE_FILE_SYSTEM_PROTOCOL.OpenVolume`.
    OpenVolume,
    /// `EFI_FILE_PROTOCOL.Open` of the file.
    Open,
    /// `EFI_FILE_PROTOCOL.GetInfo` (the file's size).
    GetInfo,
    /// `EFI_FILE_PROTOCOL.Read`.
    Read,
    /// `EFI_BOOT_SERVICES.AllocatePages` for the file's bytes.
    Allocate,
}

impl Step {
    /// The call's name, as the UEFI specification spells it.
    pub fn as_str(self) -> &'static str {
        match self {
            Step::OpenVolume => "OpenVolume",
            Step::Open => "Open",
            Step::GetInfo => "GetInfo",
            Step::Read => "Read",
            Step::Allocate => "AllocatePages",
        }
    }
}

/// Why one attempt at reading a file failed. `S` is the firmware's status
/// (its `Debug` is the status's name, such as `DEVICE_ERROR`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Failure<S> {
    /// A firmware call returned an error status.
    Status {
        /// The call.
        step: Step,
        /// What it returned.
        status: S,
    },
    /// The name is a directory, not a file.
    Directory,
    /// `Read` gave fewer bytes than `GetInfo` said the file holds.
    Short {
        /// The bytes read.
        read: usize,
        /// The file's size by its info.
        size: usize,
    },
}

impl<S> Failure<S> {
    /// Whether one more try may help: a failed read, open or info call, or a
    /// short read (a flaky stick or port). A directory, or no memory for the
    /// file, is the same the second time.
    pub fn is_retried(&self) -> bool {
        match self {
            Failure::Status { step, .. } => *step != Step::Allocate,
            Failure::Directory => false,
            Failure::Short { .. } => true,
        }
    }
}

impl<S: fmt::Debug> fmt::Display for Failure<S> {
    /// The short form, for the retry line: `DEVICE_ERROR`, `only 12 of 40
    /// bytes`, `a directory`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Failure::Status { status, .. } => write!(f, "{status:?}"),
            Failure::Directory => f.write_str("a directory"),
            Failure::Short { read, size } => write!(f, "only {read} of {size} bytes"),
        }
    }
}

/// The result of [`read_with_one_retry`]: the value, and the failure of the
/// first attempt when it took a second one.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Read<T, S> {
    /// What the successful attempt gave.
    pub value: T,
    /// The first attempt's failure, if the value came from the second.
    pub retried_after: Option<Failure<S>>,
}

/// Runs `attempt`; if it fails in a way one more try may help
/// ([`Failure::is_retried`]), calls `on_retry` with the failure and runs it
/// once more. At most two attempts; the second one's failure is returned.
pub fn read_with_one_retry<T, S: Copy>(
    mut attempt: impl FnMut() -> Result<T, Failure<S>>,
    on_retry: impl FnOnce(&Failure<S>),
) -> Result<Read<T, S>, Failure<S>> {
    match attempt() {
        Ok(value) => Ok(Read {
            value,
            retried_after: None,
        }),
        Err(first) if first.is_retried() => {
            on_retry(&first);
            attempt().map(|value| Read {
                value,
                retried_after: Some(first),
            })
        }
        Err(first) => Err(first),
    }
}

/// The line written when a first attempt failed:
/// `loader: read retried: kernel-x86_64 failed (DEVICE_ERROR); trying once more`.
pub struct RetryLine<'a, N, S> {
    /// The file's name.
    pub file: N,
    /// The first attempt's failure.
    pub failure: &'a Failure<S>,
}

impl<N: fmt::Display, S: fmt::Debug> fmt::Display for RetryLine<'_, N, S> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "loader: read retried: {} failed ({}); trying once more",
            self.file, self.failure
        )
    }
}

/// The line written when the second attempt worked.
pub struct RecoveredLine<N> {
    /// The file's name.
    pub file: N,
}

impl<N: fmt::Display> fmt::Display for RecoveredLine<N> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "loader: read retried: {} worked the second time",
            self.file
        )
    }
}

/// The message when reading a file failed for good: the file, the call, the
/// status and what to try; the loader shows it and stops.
pub struct StopMessage<'a, N, S> {
    /// The file's name.
    pub file: N,
    /// The last attempt's failure.
    pub failure: &'a Failure<S>,
}

impl<N: fmt::Display, S: fmt::Debug> fmt::Display for StopMessage<'_, N, S> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "loader: cannot read {}: ", self.file)?;
        match self.failure {
            Failure::Status {
                step: Step::Allocate,
                status,
            } => write!(
                f,
                "no memory for it (AllocatePages: {status:?}). Try with fewer devices \
                 plugged in, or another machine."
            )?,
            Failure::Status { step, status } => write!(
                f,
                "{} returned {status:?}, twice. Write the stick again, or try another \
                 USB port.",
                step.as_str()
            )?,
            Failure::Directory => f.write_str("it is a directory. Write the stick again.")?,
            Failure::Short { read, size } => write!(
                f,
                "Read gave only {read} of its {size} bytes, twice. Write the stick again, \
                 or try another USB port."
            )?,
        }
        f.write_str(" The loader stops here.")
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::format;
    use std::string::String;
    use std::vec::Vec;

    #[derive(Clone, Copy, Debug, PartialEq, Eq)]
    #[allow(non_camel_case_types)]
    enum Status {
        DEVICE_ERROR,
        OUT_OF_RESOURCES,
    }

    const DEVICE_ERROR: Failure<Status> = Failure::Status {
        step: Step::Read,
        status: Status::DEVICE_ERROR,
    };

    /// What [`run`] gives: the policy's result, the attempts, the retry lines.
    type Run = (
        Result<Read<u32, Status>, Failure<Status>>,
        usize,
        Vec<String>,
    );

    /// Runs the policy over scripted attempt results; gives what it returned,
    /// how many attempts ran and the retry lines written.
    fn run(script: &[Result<u32, Failure<Status>>]) -> Run {
        let mut calls = 0;
        let mut lines = Vec::new();
        let result = read_with_one_retry(
            || {
                calls += 1;
                script[calls - 1]
            },
            |failure| {
                lines.push(format!(
                    "{}",
                    RetryLine {
                        file: "kernel-x86_64",
                        failure
                    }
                ))
            },
        );
        (result, calls, lines)
    }

    #[test]
    fn a_first_success_is_read_once_without_a_retry_line() {
        let (result, calls, lines) = run(&[Ok(7)]);
        assert_eq!(
            result,
            Ok(Read {
                value: 7,
                retried_after: None
            })
        );
        assert_eq!(calls, 1);
        assert!(lines.is_empty());
    }

    #[test]
    fn a_failed_read_is_tried_once_more_and_the_log_says_so() {
        let (result, calls, lines) = run(&[Err(DEVICE_ERROR), Ok(7)]);
        assert_eq!(
            result,
            Ok(Read {
                value: 7,
                retried_after: Some(DEVICE_ERROR)
            })
        );
        assert_eq!(calls, 2);
        assert_eq!(
            lines,
            ["loader: read retried: kernel-x86_64 failed (DEVICE_ERROR); trying once more"]
        );
    }

    #[test]
    fn a_failure_that_stays_is_tried_exactly_twice() {
        let short = Failure::Short { read: 12, size: 40 };
        let (result, calls, lines) = run(&[Err(DEVICE_ERROR), Err(short), Ok(7)]);
        assert_eq!(result, Err(short));
        assert_eq!(calls, 2);
        assert_eq!(lines.len(), 1);
    }

    #[test]
    fn a_short_read_is_retried_too() {
        let short = Failure::Short { read: 12, size: 40 };
        let (result, calls, lines) = run(&[Err(short), Ok(7)]);
        assert_eq!(result.map(|r| r.value), Ok(7));
        assert_eq!(calls, 2);
        assert_eq!(
            lines,
            ["loader: read retried: kernel-x86_64 failed (only 12 of 40 bytes); trying once more"]
        );
    }

    #[test]
    fn a_directory_or_no_memory_is_not_retried() {
        let no_memory = Failure::Status {
            step: Step::Allocate,
            status: Status::OUT_OF_RESOURCES,
        };
        for failure in [Failure::Directory, no_memory] {
            let (result, calls, lines) = run(&[Err(failure), Ok(7)]);
            assert_eq!(result, Err(failure));
            assert_eq!(calls, 1);
            assert!(lines.is_empty());
        }
    }

    #[test]
    fn every_call_is_retried_but_the_allocation() {
        for step in [Step::OpenVolume, Step::Open, Step::GetInfo, Step::Read] {
            let failure = Failure::Status {
                step,
                status: Status::DEVICE_ERROR,
            };
            assert!(failure.is_retried(), "{step:?}");
        }
    }

    #[test]
    fn the_stop_message_names_the_file_the_call_the_status_and_what_to_try() {
        let text = format!(
            "{}",
            StopMessage {
                file: "kernel-x86_64",
                failure: &DEVICE_ERROR
            }
        );
        assert_eq!(
            text,
            "loader: cannot read kernel-x86_64: Read returned DEVICE_ERROR, twice. Write the \
             stick again, or try another USB port. The loader stops here."
        );
        let short = format!(
            "{}",
            StopMessage {
                file: "kernel-x86_64",
                failure: &Failure::<Status>::Short { read: 3, size: 9 }
            }
        );
        assert!(short.contains("only 3 of its 9 bytes"), "{short}");
        assert!(short.contains("Write the stick again"), "{short}");
        let memory = format!(
            "{}",
            StopMessage {
                file: "ramdisk",
                failure: &Failure::Status {
                    step: Step::Allocate,
                    status: Status::OUT_OF_RESOURCES
                }
            }
        );
        assert!(memory.contains("OUT_OF_RESOURCES"), "{memory}");
        assert!(!memory.contains("stick"), "{memory}");
        assert_eq!(
            format!("{}", RecoveredLine { file: "boot.json" }),
            "loader: read retried: boot.json worked the second time"
        );
    }
}
