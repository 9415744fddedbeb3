//! Errors of the format crate: where it went wrong (file, block, byte) and what (a stable code).

use std::fmt;
use std::sync::Arc;

/// Stable issue codes, shared by reader errors and `verify` reports (spec §13).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[non_exhaustive]
pub enum Code {
    Io,
    FileTooSmall,
    HeaderMagic,
    HeaderVersionUnsupported,
    HeaderMinorNewer,
    HeaderChecksum,
    HeaderReserved,
    HeaderBlockSize,
    HeaderFeatureUnsupported,
    HeaderFeatureUnknown,
    HeaderFeatureMismatch,
    TrailerMagic,
    TrailerChecksum,
    Layout,
    DirectoryChecksum,
    RootChecksum,
    EntryKind,
    EntryCodec,
    EntryReserved,
    EntryLength,
    EntryOffset,
    EntryLevel,
    EntryItemCount,
    MetadataChecksum,
    MetadataDecode,
    MetadataNonCanonical,
    MetadataLimit,
    LimitExceeded,
    BlockChecksum,
    BlockDecompress,
    TreeletLayout,
    NodeType,
    NodeField,
    NodeChild,
    NodeOverlap,
    NodeOrder,
    Voxel,
    Rlod,
    LodArea,
    TriangleLayout,
    TriangleIndex,
    TriangleAttributes,
    VertexNotFinite,
    ProxyLayout,
    TreeRoot,
    TreeReference,
    TreeLevel,
    TreeShared,
    TreeUnreachable,
    TreeDepth,
    TreeSplit,
    TreeLodRadius,
    TreeMaterial,
    TreeCounts,
    TreeEmpty,
    /// A bad argument given to the writer or reader API (not a file problem).
    InvalidParameter,
}

/// How bad an issue is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Severity {
    Info,
    Warning,
    Error,
}

impl Code {
    /// Every code, in spec order (the spec cross-check test walks this list).
    pub const ALL: &'static [Code] = &[
        Code::Io,
        Code::FileTooSmall,
        Code::HeaderMagic,
        Code::HeaderVersionUnsupported,
        Code::HeaderMinorNewer,
        Code::HeaderChecksum,
        Code::HeaderReserved,
        Code::HeaderBlockSize,
        Code::HeaderFeatureUnsupported,
        Code::HeaderFeatureUnknown,
        Code::HeaderFeatureMismatch,
        Code::TrailerMagic,
        Code::TrailerChecksum,
        Code::Layout,
        Code::DirectoryChecksum,
        Code::RootChecksum,
        Code::EntryKind,
        Code::EntryCodec,
        Code::EntryReserved,
        Code::EntryLength,
        Code::EntryOffset,
        Code::EntryLevel,
        Code::EntryItemCount,
        Code::MetadataChecksum,
        Code::MetadataDecode,
        Code::MetadataNonCanonical,
        Code::MetadataLimit,
        Code::LimitExceeded,
        Code::BlockChecksum,
        Code::BlockDecompress,
        Code::TreeletLayout,
        Code::NodeType,
        Code::NodeField,
        Code::NodeChild,
        Code::NodeOverlap,
        Code::NodeOrder,
        Code::Voxel,
        Code::Rlod,
        Code::LodArea,
        Code::TriangleLayout,
        Code::TriangleIndex,
        Code::TriangleAttributes,
        Code::VertexNotFinite,
        Code::ProxyLayout,
        Code::TreeRoot,
        Code::TreeReference,
        Code::TreeLevel,
        Code::TreeShared,
        Code::TreeUnreachable,
        Code::TreeDepth,
        Code::TreeSplit,
        Code::TreeLodRadius,
        Code::TreeMaterial,
        Code::TreeCounts,
        Code::TreeEmpty,
    ];

    pub fn as_str(self) -> &'static str {
        match self {
            Code::Io => "IO",
            Code::FileTooSmall => "FILE_TOO_SMALL",
            Code::HeaderMagic => "HEADER_MAGIC",
            Code::HeaderVersionUnsupported => "HEADER_VERSION_UNSUPPORTED",
            Code::HeaderMinorNewer => "HEADER_MINOR_NEWER",
            Code::HeaderChecksum => "HEADER_CHECKSUM",
            Code::HeaderReserved => "HEADER_RESERVED",
            Code::HeaderBlockSize => "HEADER_BLOCK_SIZE",
            Code::HeaderFeatureUnsupported => "HEADER_FEATURE_UNSUPPORTED",
            Code::HeaderFeatureUnknown => "HEADER_FEATURE_UNKNOWN",
            Code::HeaderFeatureMismatch => "HEADER_FEATURE_MISMATCH",
            Code::TrailerMagic => "TRAILER_MAGIC",
            Code::TrailerChecksum => "TRAILER_CHECKSUM",
            Code::Layout => "LAYOUT",
            Code::DirectoryChecksum => "DIRECTORY_CHECKSUM",
            Code::RootChecksum => "ROOT_CHECKSUM",
            Code::EntryKind => "ENTRY_KIND",
            Code::EntryCodec => "ENTRY_CODEC",
            Code::EntryReserved => "ENTRY_RESERVED",
            Code::EntryLength => "ENTRY_LENGTH",
            Code::EntryOffset => "ENTRY_OFFSET",
            Code::EntryLevel => "ENTRY_LEVEL",
            Code::EntryItemCount => "ENTRY_ITEM_COUNT",
            Code::MetadataChecksum => "METADATA_CHECKSUM",
            Code::MetadataDecode => "METADATA_DECODE",
            Code::MetadataNonCanonical => "METADATA_NON_CANONICAL",
            Code::MetadataLimit => "METADATA_LIMIT",
            Code::LimitExceeded => "LIMIT_EXCEEDED",
            Code::BlockChecksum => "BLOCK_CHECKSUM",
            Code::BlockDecompress => "BLOCK_DECOMPRESS",
            Code::TreeletLayout => "TREELET_LAYOUT",
            Code::NodeType => "NODE_TYPE",
            Code::NodeField => "NODE_FIELD",
            Code::NodeChild => "NODE_CHILD",
            Code::NodeOverlap => "NODE_OVERLAP",
            Code::NodeOrder => "NODE_ORDER",
            Code::Voxel => "VOXEL",
            Code::Rlod => "RLOD",
            Code::LodArea => "LOD_AREA",
            Code::TriangleLayout => "TRIANGLE_LAYOUT",
            Code::TriangleIndex => "TRIANGLE_INDEX",
            Code::TriangleAttributes => "TRIANGLE_ATTRIBUTES",
            Code::VertexNotFinite => "VERTEX_NOT_FINITE",
            Code::ProxyLayout => "PROXY_LAYOUT",
            Code::TreeRoot => "TREE_ROOT",
            Code::TreeReference => "TREE_REFERENCE",
            Code::TreeLevel => "TREE_LEVEL",
            Code::TreeShared => "TREE_SHARED",
            Code::TreeUnreachable => "TREE_UNREACHABLE",
            Code::TreeDepth => "TREE_DEPTH",
            Code::TreeSplit => "TREE_SPLIT",
            Code::TreeLodRadius => "TREE_LOD_RADIUS",
            Code::TreeMaterial => "TREE_MATERIAL",
            Code::TreeCounts => "TREE_COUNTS",
            Code::TreeEmpty => "TREE_EMPTY",
            Code::InvalidParameter => "INVALID_PARAMETER",
        }
    }

    /// The severity the spec gives this code.
    pub fn severity(self) -> Severity {
        match self {
            Code::HeaderMinorNewer | Code::HeaderFeatureUnknown => Severity::Info,
            Code::HeaderFeatureMismatch | Code::TreeUnreachable | Code::TreeEmpty => {
                Severity::Warning
            }
            _ => Severity::Error,
        }
    }
}

impl fmt::Display for Code {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// What went wrong, without the place.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ErrorKind {
    #[error("I/O error: {0}")]
    Io(#[from] std::io::Error),
    #[error("{what} checksum mismatch: stored {stored:#010x}, computed {computed:#010x}")]
    Checksum {
        code: Code,
        what: &'static str,
        stored: u32,
        computed: u32,
    },
    #[error("unsupported: {detail}")]
    Unsupported { code: Code, detail: String },
    #[error("{what} needs {requested} bytes, over the limit of {limit}")]
    Limit {
        code: Code,
        what: &'static str,
        requested: u64,
        limit: u64,
    },
    #[error("{detail}")]
    Malformed { code: Code, detail: String },
    #[error("invalid parameter: {0}")]
    Parameter(String),
}

impl ErrorKind {
    pub fn code(&self) -> Code {
        match self {
            ErrorKind::Io(_) => Code::Io,
            ErrorKind::Checksum { code, .. }
            | ErrorKind::Unsupported { code, .. }
            | ErrorKind::Limit { code, .. }
            | ErrorKind::Malformed { code, .. } => *code,
            ErrorKind::Parameter(_) => Code::InvalidParameter,
        }
    }
}

/// An error with its place: the file, and where known the block id and byte offset.
#[derive(Debug)]
pub struct Error {
    pub file: Option<Arc<str>>,
    pub block: Option<u32>,
    pub offset: Option<u64>,
    pub kind: ErrorKind,
}

impl Error {
    pub fn new(kind: ErrorKind) -> Self {
        Error {
            file: None,
            block: None,
            offset: None,
            kind,
        }
    }

    pub fn malformed(code: Code, detail: impl Into<String>) -> Self {
        Error::new(ErrorKind::Malformed {
            code,
            detail: detail.into(),
        })
    }

    pub fn limit(what: &'static str, requested: u64, limit: u64) -> Self {
        Error::new(ErrorKind::Limit {
            code: Code::LimitExceeded,
            what,
            requested,
            limit,
        })
    }

    pub fn parameter(detail: impl Into<String>) -> Self {
        Error::new(ErrorKind::Parameter(detail.into()))
    }

    pub fn io(err: std::io::Error, offset: u64) -> Self {
        Error::new(ErrorKind::Io(err)).at(offset)
    }

    pub fn code(&self) -> Code {
        self.kind.code()
    }

    pub fn at(mut self, offset: u64) -> Self {
        self.offset.get_or_insert(offset);
        self
    }

    pub fn in_block(mut self, block: u32) -> Self {
        self.block.get_or_insert(block);
        self
    }

    pub fn in_file(mut self, file: &Arc<str>) -> Self {
        if self.file.is_none() {
            self.file = Some(Arc::clone(file));
        }
        self
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some(file) = &self.file {
            write!(f, "{file}: ")?;
        }
        if let Some(block) = self.block {
            write!(f, "block {block}: ")?;
        }
        if let Some(offset) = self.offset {
            write!(f, "byte {offset}: ")?;
        }
        write!(f, "{} [{}]", self.kind, self.code())
    }
}

impl std::error::Error for Error {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match &self.kind {
            ErrorKind::Io(e) => Some(e),
            _ => None,
        }
    }
}

impl From<std::io::Error> for Error {
    fn from(e: std::io::Error) -> Self {
        Error::new(ErrorKind::Io(e))
    }
}

pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Shorthand for a `Malformed` error result.
pub(crate) fn bad<T>(code: Code, detail: impl Into<String>) -> Result<T> {
    Err(Error::malformed(code, detail))
}
