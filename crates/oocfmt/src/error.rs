//! Errors of the format crate: where it went wrong (file, block, byte) and what (a stable code).

use std::fmt;
use std::sync::Arc;

/// Stable issue codes, shared by reader errors and `verify` reports (spec §13).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
#[non_exhaustive]
pub enum Code {
    /// The file could not be read (an I/O failure, not a format problem; `verify` exits 2).
    Io,
    /// The file is shorter than a header and a trailer.
    FileTooSmall,
    /// Not an `.oocf` file, or one mangled by a text-mode transfer.
    HeaderMagic,
    /// A major version this reader does not implement.
    HeaderVersionUnsupported,
    /// A newer minor version: the fields it adds are ignored (info).
    HeaderMinorNewer,
    /// The header's CRC does not match its bytes.
    HeaderChecksum,
    /// Reserved header bytes are not zero.
    HeaderReserved,
    /// `block_size_log2` is outside 12 ..= 20.
    HeaderBlockSize,
    /// An incompatible feature bit this reader does not know; the file is refused.
    HeaderFeatureUnsupported,
    /// A compatible feature bit this reader does not know (info).
    HeaderFeatureUnknown,
    /// `PROXIES` or `LOD_VOXELS` does not match the content (warning, deep only).
    HeaderFeatureMismatch,
    /// No end magic: the file is truncated, was interrupted, or has bytes appended.
    TrailerMagic,
    /// The trailer's CRC does not match its bytes.
    TrailerChecksum,
    /// Header and trailer disagree, or the regions do not tile the file (spec §2).
    Layout,
    /// The directory's CRC does not match the one in the trailer.
    DirectoryChecksum,
    /// The root checksum (the file identity) does not match header, directory and metadata.
    RootChecksum,
    /// A directory entry names an unknown block kind.
    EntryKind,
    /// A directory entry names an unknown codec.
    EntryCodec,
    /// Reserved directory entry bytes are not zero.
    EntryReserved,
    /// `raw_length` or `stored_length` is out of range for the block size and codec.
    EntryLength,
    /// A block is not where spec §4 puts it (a gap, an overlap, or outside the file).
    EntryOffset,
    /// A non-treelet block has a non-zero level, or treelet levels are not in order.
    EntryLevel,
    /// `item_count` is zero, more than the raw length can hold, or not what the block holds.
    EntryItemCount,
    /// The metadata's CRC does not match the one in the trailer.
    MetadataChecksum,
    /// Not a valid postcard `Metadata`, bytes left over, or a value breaking a rule of spec §9.
    MetadataDecode,
    /// The metadata decodes but is not the canonical encoding of its value (an over-long varint).
    MetadataNonCanonical,
    /// The metadata is longer than the configured limit.
    MetadataLimit,
    /// The part table breaks a rule of spec §9 (a parent not before its child, an unknown
    /// source, a non-finite bound, too many parts), or disagrees with the `PART_IDS` bit.
    PartTable,
    /// A size in the file exceeds a reader limit (spec §12).
    LimitExceeded,
    /// A block's stored bytes do not match the CRC in its directory entry.
    BlockChecksum,
    /// The codec failed or gave a length other than `raw_length`, or a zstd frame rule is broken.
    BlockDecompress,
    /// A treelet block's header, start offsets or section sizes are invalid.
    TreeletLayout,
    /// A node has the reserved type 3.
    NodeType,
    /// An invalid axis, reserved bits set, both children empty, or a non-finite split or radius.
    NodeField,
    /// A child offset is not forward, does not match its empty flag, or leaves the treelet.
    NodeChild,
    /// A node before its preorder position or past its treelet's end, or bytes after the last node.
    NodeOverlap,
    /// A node starts after its preorder position: the treelet is not in strict preorder.
    NodeOrder,
    /// A voxel offset is outside the LOD area or unaligned, or a shading sample is invalid.
    Voxel,
    /// An R-LOD record misplaced or invalid, or (deep) a plane missing its node's enclosing sphere.
    Rlod,
    /// The LOD entries do not tile the LOD area in node order (a gap, stray bytes, a shared entry).
    LodArea,
    /// A triangle block's header or section sizes are invalid.
    TriangleLayout,
    /// A list entry is not below the triangle count, or a vertex index not below the vertex count.
    TriangleIndex,
    /// A triangle block's attribute bits differ from the metadata schema.
    TriangleAttributes,
    /// A vertex position is NaN or infinite.
    VertexNotFinite,
    /// A triangle's or a LOD entry's part id is not below the number of parts.
    PartId,
    /// A proxy block's length is not 80 × `item_count`, or a proxy record is invalid.
    ProxyLayout,
    /// The root is missing, or is not a treelet of a level-0 treelet block.
    TreeRoot,
    /// A block, treelet, list range or proxy named in the tree is out of range or of a wrong kind.
    TreeReference,
    /// A LOD node's child block is not of the next level.
    TreeLevel,
    /// A treelet is reached twice from the root.
    TreeShared,
    /// A treelet is never reached from the root (warning).
    TreeUnreachable,
    /// A root-to-leaf path longer than 128 node levels.
    TreeDepth,
    /// A split plane lies outside its node's cell, so a child cell would leave its parent's.
    TreeSplit,
    /// A LOD radius is larger than an ancestor's, or smaller than its cell's half diagonal.
    TreeLodRadius,
    /// A triangle's material index is not below the number of materials.
    TreeMaterial,
    /// The counts or schema in the metadata differ from what the tree holds.
    TreeCounts,
    /// A part's triangle count differs from the primaries that carry its id (deep).
    PartCounts,
    /// A part's bounds are not the exact box of its triangles' corners (deep).
    PartBounds,
    /// The file holds no geometry (warning).
    TreeEmpty,
    /// A bad argument given to the writer or reader API (not a file problem).
    InvalidParameter,
}

/// How bad an issue is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Severity {
    /// Worth knowing, says nothing against the file (a newer minor version, an unknown
    /// compatible feature).
    Info,
    /// The file is valid but suspicious (unreachable treelets, no geometry).
    Warning,
    /// The file is invalid: `verify` exits 1, and a reader refuses it where it checks the rule.
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
        Code::PartTable,
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
        Code::PartId,
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
        Code::PartCounts,
        Code::PartBounds,
        Code::TreeEmpty,
    ];

    /// The code's stable name, as the spec and the JSON report spell it (`BLOCK_CHECKSUM`).
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
            Code::PartTable => "PART_TABLE",
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
            Code::PartId => "PART_ID",
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
            Code::PartCounts => "PART_COUNTS",
            Code::PartBounds => "PART_BOUNDS",
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
    /// Reading or writing the file failed; code `IO`.
    #[error("I/O error: {0}")]
    Io(#[from] std::io::Error),
    /// A CRC-32C stored in the file does not match the bytes it covers.
    #[error("{what} checksum mismatch: stored {stored:#010x}, computed {computed:#010x}")]
    Checksum {
        /// Which checksum code applies (`HEADER_CHECKSUM`, `BLOCK_CHECKSUM`, ...).
        code: Code,
        /// The part of the file the checksum covers, for the message (`"block"`, `"header"`).
        what: &'static str,
        /// The CRC the file stores.
        stored: u32,
        /// The CRC of the bytes as read.
        computed: u32,
    },
    /// The file uses something this reader does not implement (a major version, a feature bit).
    #[error("unsupported: {detail}")]
    Unsupported {
        /// The code naming what is unsupported.
        code: Code,
        /// What was found, for a person to read.
        detail: String,
    },
    /// A size stated by the file is over a reader limit (spec §12), refused before allocating.
    #[error("{what} needs {requested} bytes, over the limit of {limit}")]
    Limit {
        /// `LIMIT_EXCEEDED`, or `METADATA_LIMIT` for the metadata length.
        code: Code,
        /// What the size is of, for the message (`"resident proxies"`).
        what: &'static str,
        /// Bytes the file asks for.
        requested: u64,
        /// The limit in bytes that it exceeds.
        limit: u64,
    },
    /// The bytes break a rule of the spec; `code` names the rule.
    #[error("{detail}")]
    Malformed {
        /// The stable code of the broken rule.
        code: Code,
        /// What was found and where in the structure, for a person to read.
        detail: String,
    },
    /// A caller passed a bad argument to the API; code `INVALID_PARAMETER`, not a file problem.
    #[error("invalid parameter: {0}")]
    Parameter(String),
}

impl ErrorKind {
    /// The stable code of this error, as `verify` would report it.
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
    /// The file's path as the caller named it, when the error has been tied to one.
    pub file: Option<Arc<str>>,
    /// The block id (index in the directory) the problem is in, when it is in one.
    pub block: Option<u32>,
    /// Byte offset in the file where the problem was found, when known.
    pub offset: Option<u64>,
    /// What went wrong.
    pub kind: ErrorKind,
}

impl Error {
    /// An error of `kind` with no place yet; [`Error::at`], [`Error::in_block`] and
    /// [`Error::in_file`] add it as the error travels up.
    pub fn new(kind: ErrorKind) -> Self {
        Error {
            file: None,
            block: None,
            offset: None,
            kind,
        }
    }

    /// A [`ErrorKind::Malformed`] error: the bytes break the rule `code` names.
    pub fn malformed(code: Code, detail: impl Into<String>) -> Self {
        Error::new(ErrorKind::Malformed {
            code,
            detail: detail.into(),
        })
    }

    /// A `LIMIT_EXCEEDED` error: `what` needs `requested` bytes, over `limit` bytes.
    pub fn limit(what: &'static str, requested: u64, limit: u64) -> Self {
        Error::new(ErrorKind::Limit {
            code: Code::LimitExceeded,
            what,
            requested,
            limit,
        })
    }

    /// An `INVALID_PARAMETER` error: a bad argument from the caller, not from the file.
    pub fn parameter(detail: impl Into<String>) -> Self {
        Error::new(ErrorKind::Parameter(detail.into()))
    }

    /// An `IO` error from reading at byte `offset`.
    pub fn io(err: std::io::Error, offset: u64) -> Self {
        Error::new(ErrorKind::Io(err)).at(offset)
    }

    /// The stable code of the error's kind.
    pub fn code(&self) -> Code {
        self.kind.code()
    }

    /// Sets the byte offset unless one is already set: the innermost, most precise place wins.
    pub fn at(mut self, offset: u64) -> Self {
        self.offset.get_or_insert(offset);
        self
    }

    /// Sets the block id unless one is already set.
    pub fn in_block(mut self, block: u32) -> Self {
        self.block.get_or_insert(block);
        self
    }

    /// Sets the file name unless one is already set.
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

/// The crate's result type, with [`Error`] as the default error.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Shorthand for a `Malformed` error result.
pub(crate) fn bad<T>(code: Code, detail: impl Into<String>) -> Result<T> {
    Err(Error::malformed(code, detail))
}
