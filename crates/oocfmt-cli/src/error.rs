//! The CLI's errors and the exit codes they map to: the only place errors become exit codes.
//! The library errors are kept as they are (typed, each saying what and where) and sorted
//! into the codes here, in [`CliError::exit_code`]:
//!
//! - [`EXIT_INVALID`] (1): an input is invalid: a container fails verification or cannot be
//!   read as one, a model cannot be imported or built into one;
//! - [`EXIT_USAGE`] (2): the command could not run: bad usage (a flag, a value, a combination,
//!   a LOD kind the file lacks, a bad camera path), or an I/O error (a missing input, an
//!   output that cannot be written);
//! - [`EXIT_INTERNAL`] (3): a bug in oocfmt: a report that cannot be written as JSON, an
//!   invariant of the builder that broke, images that should match in size and do not.
//!
//! - 128 + the signal's number: `convert` stopped by a signal ([`CliError::Interrupted`]):
//!   130 for SIGINT (Ctrl-C), 143 for SIGTERM, as a shell reports a process the signal ended;
//! - [`EXIT_BROKEN_PIPE`] (141, 128 + SIGPIPE): `gen -o -` found standard output closed
//!   before the model was written.
//!
//! 0 is success; `verify` also exits 1 for a file it finds invalid.

use oocfmt_build::convert::ConvertError;
use oocfmt_build::kdtree::KdError;
use oocfmt_build::layout::LayoutError;
use oocfmt_build::ooc::OocError;
use oocfmt_build::subsets::SubsetError;
use oocfmt_meshio::export::ExportError;
use oocfmt_meshio::import::ImportError;
use oocfmt_scenes::GenError;
use oocfmt_trace::compare::SizeMismatch;
use oocfmt_trace::TraceError;

/// An input is invalid.
pub const EXIT_INVALID: u8 = 1;
/// The command could not run: usage or I/O.
pub const EXIT_USAGE: u8 = 2;
/// A bug in oocfmt.
pub const EXIT_INTERNAL: u8 = 3;
/// Interrupted by SIGINT (Ctrl-C): 128 + 2.
pub const EXIT_SIGINT: u8 = 130;
/// The reader of standard output went away: 128 + SIGPIPE (13).
pub const EXIT_BROKEN_PIPE: u8 = 141;

#[derive(Debug, thiserror::Error)]
pub enum CliError {
    #[error("{0}")]
    Format(#[from] oocfmt::Error),
    #[error("{0}")]
    Usage(String),
    #[error("{path}: {source}")]
    Io {
        path: String,
        source: std::io::Error,
    },
    #[error("{0}")]
    Trace(#[from] TraceError),
    #[error("{0}")]
    Convert(#[from] ConvertError),
    #[error("{0}")]
    Export(#[from] ExportError),
    #[error("{0}")]
    Gen(#[from] GenError),
    /// Two images compared that should have the same size.
    #[error("{0}")]
    Compare(#[from] SizeMismatch),
    #[error("JSON output failed: {0}")]
    Json(#[from] serde_json::Error),
    /// `convert` stopped by a signal; `code` is 128 + its number.
    #[error("{source}")]
    Interrupted { code: u8, source: ConvertError },
    /// `plan`, `convert --plan` or `merge` failed.
    #[error("{0}")]
    Subsets(#[from] SubsetError),
    /// `plan`, `convert --plan` or `merge` stopped by a signal; `code` is 128 + its number.
    #[error("{source}")]
    SubsetsInterrupted { code: u8, source: SubsetError },
}

impl CliError {
    /// The exit code of this error (the module documentation says what each means).
    pub fn exit_code(&self) -> u8 {
        use CliError as C;
        match self {
            C::Format(e)
            | C::Trace(TraceError::Format(e))
            | C::Export(ExportError::Format(e))
            | C::Convert(
                ConvertError::Format(e)
                | ConvertError::Layout(LayoutError::Format(e))
                | ConvertError::OutOfCore(
                    OocError::Format(e) | OocError::Layout(LayoutError::Format(e)),
                ),
            ) => format_exit_code(e),
            C::Usage(_)
            | C::Io { .. }
            | C::Trace(
                TraceError::Io { .. }
                | TraceError::Png { .. }
                | TraceError::Camera(_)
                | TraceError::Options(_)
                | TraceError::Path { .. }
                | TraceError::LodKind { .. },
            )
            | C::Convert(
                ConvertError::UnknownFormat(_)
                | ConvertError::StdinFormat
                | ConvertError::StdinGltf
                | ConvertError::StdinTwice
                | ConvertError::StdinRecentre
                | ConvertError::SpillDir { .. }
                | ConvertError::Import(ImportError::Io { .. })
                | ConvertError::OutOfCore(
                    OocError::Spill { .. }
                    | OocError::SpillWrite { .. }
                    | OocError::SpillLength { .. }
                    | OocError::SpillCorrupt { .. }
                    | OocError::NoSpace(_)
                    | OocError::Import(ImportError::Io { .. }),
                ),
            )
            | C::Export(ExportError::Write(_))
            | C::Gen(GenError::Write(_) | GenError::Option(_) | GenError::TooLarge(_)) => {
                EXIT_USAGE
            }
            C::Convert(
                ConvertError::Tree(e)
                | ConvertError::Layout(LayoutError::Tree(e))
                | ConvertError::OutOfCore(OocError::Tree(e) | OocError::Layout(LayoutError::Tree(e))),
            ) => match e {
                KdError::MaxLeafTriangles(_) | KdError::MaxDepth(_) | KdError::BadOption { .. } => {
                    EXIT_USAGE
                }
                _ => EXIT_INVALID,
            },
            C::Convert(ConvertError::Layout(l) | ConvertError::OutOfCore(OocError::Layout(l))) => {
                match l {
                    LayoutError::Internal(_) => EXIT_INTERNAL,
                    LayoutError::TreeletHeight(_) | LayoutError::VoxelThreshold(_) => EXIT_USAGE,
                    _ => EXIT_INVALID,
                }
            }
            C::Convert(
                ConvertError::Import(_)
                | ConvertError::OutOfCore(OocError::Import(_) | OocError::BlockFile(_)),
            )
            | C::Export(
                ExportError::CountMismatch { .. }
                | ExportError::PartCountMismatch { .. }
                | ExportError::MaterialOutOfRange { .. }
                | ExportError::TooManyVertices { .. }
                | ExportError::Changed { .. },
            ) => EXIT_INVALID,
            C::Compare(_) | C::Json(_) => EXIT_INTERNAL,
            C::Interrupted { code, .. } | C::SubsetsInterrupted { code, .. } => *code,
            C::Subsets(e) => subsets_exit_code(e),
            // Stopped on request, with no signal to tell which.
            C::Convert(ConvertError::Interrupted { .. }) => EXIT_SIGINT,
        }
    }
}

/// The exit code of a split build's error: a damaged subset file or plan, or a model that
/// cannot be imported, is invalid input; a wrong set of files, a changed input or an I/O
/// failure could not run.
fn subsets_exit_code(e: &SubsetError) -> u8 {
    use SubsetError as S;
    match e {
        S::Corrupt { .. } | S::Plan { .. } | S::OutOfCore(OocError::BlockFile(_)) => EXIT_INVALID,
        S::Import(ImportError::Io { .. })
        | S::OutOfCore(OocError::Import(ImportError::Io { .. })) => EXIT_USAGE,
        S::Import(_) | S::OutOfCore(OocError::Import(_)) => EXIT_INVALID,
        S::OutOfCore(OocError::Format(f) | OocError::Layout(LayoutError::Format(f))) => {
            format_exit_code(f)
        }
        S::Convert(c) => match &**c {
            ConvertError::Import(ImportError::Io { .. }) => EXIT_USAGE,
            ConvertError::Import(_) => EXIT_INVALID,
            ConvertError::Format(f) => format_exit_code(f),
            _ => EXIT_USAGE,
        },
        S::OutOfCore(
            OocError::Spill { .. }
            | OocError::SpillWrite { .. }
            | OocError::SpillLength { .. }
            | OocError::SpillCorrupt { .. }
            | OocError::NoSpace(_),
        ) => EXIT_USAGE,
        S::Layout(LayoutError::Internal(_))
        | S::OutOfCore(OocError::Layout(LayoutError::Internal(_)))
        | S::Internal(_)
        | S::Json(_) => EXIT_INTERNAL,
        S::Layout(_) | S::OutOfCore(_) => EXIT_INVALID,
        S::Interrupted { .. } => EXIT_SIGINT,
        S::Io { .. }
        | S::InputChanged { .. }
        | S::Stdin
        | S::TooManySubsets
        | S::NoSuchSubset { .. }
        | S::NoSubsets
        | S::Missing { .. }
        | S::Duplicate { .. }
        | S::Foreign { .. } => EXIT_USAGE,
    }
}

/// A format error is the file's fault unless it is an I/O failure or an option the caller
/// passed.
fn format_exit_code(e: &oocfmt::Error) -> u8 {
    match e.code() {
        oocfmt::Code::Io | oocfmt::Code::InvalidParameter => EXIT_USAGE,
        _ => EXIT_INVALID,
    }
}

pub type CliResult = Result<u8, CliError>;

pub fn to_json<T: serde::Serialize>(value: &T) -> Result<String, CliError> {
    Ok(serde_json::to_string_pretty(value)?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn errors_map_to_their_documented_codes() {
        let io = || std::io::Error::other("disk full");
        assert_eq!(CliError::Usage("x".into()).exit_code(), EXIT_USAGE);
        assert_eq!(
            CliError::Trace(TraceError::Options("x".into())).exit_code(),
            EXIT_USAGE
        );
        assert_eq!(
            CliError::Convert(ConvertError::UnknownFormat("a.3ds".into())).exit_code(),
            EXIT_USAGE
        );
        assert_eq!(
            CliError::Convert(ConvertError::Import(ImportError::Empty { dropped: 1 })).exit_code(),
            EXIT_INVALID
        );
        assert_eq!(
            CliError::Convert(ConvertError::Layout(LayoutError::Internal("x"))).exit_code(),
            EXIT_INTERNAL
        );
        assert_eq!(
            CliError::Convert(ConvertError::OutOfCore(OocError::Spill {
                path: "s".into(),
                source: io()
            }))
            .exit_code(),
            EXIT_USAGE
        );
        assert_eq!(
            CliError::Convert(ConvertError::Tree(KdError::MaxLeafTriangles(0))).exit_code(),
            EXIT_USAGE
        );
        assert_eq!(
            CliError::Convert(ConvertError::Tree(KdError::TooManyNodes)).exit_code(),
            EXIT_INVALID
        );
        assert_eq!(
            CliError::Convert(ConvertError::StdinFormat).exit_code(),
            EXIT_USAGE
        );
        let stopped = || ConvertError::Interrupted {
            output: "o.oocf".into(),
            spill_bytes: 0,
        };
        assert_eq!(CliError::Convert(stopped()).exit_code(), EXIT_SIGINT);
        let term = CliError::Interrupted {
            code: 143,
            source: stopped(),
        };
        assert_eq!(term.exit_code(), 143);
        assert_eq!(
            CliError::Gen(GenError::Option("x".into())).exit_code(),
            EXIT_USAGE
        );
        assert_eq!(
            CliError::Export(ExportError::Changed { file: "f".into() }).exit_code(),
            EXIT_INVALID
        );
        let json = serde_json::from_str::<u8>("x").err();
        if let Some(e) = json {
            assert_eq!(CliError::Json(e).exit_code(), EXIT_INTERNAL);
        }
    }
}
