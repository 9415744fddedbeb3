//! The verify report: issues with stable codes, and the versioned JSON schema around them.

use serde::Serialize;

use crate::error::{Code, Error, Severity};

/// The report schema's name and version; bump the number on any incompatible change.
pub const REPORT_SCHEMA: &str = "oocfmt-verify/1";

/// One problem found in the file.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Issue {
    /// The stable code of the broken rule; serialised as its name (`BLOCK_CHECKSUM`).
    #[serde(serialize_with = "code_str")]
    pub code: Code,
    /// The severity the spec gives the code.
    pub severity: Severity,
    /// What was found, for a person to read; the place is in `block` and `offset`.
    pub message: String,
    /// The block id the issue is in, when it is in one; left out of the JSON when `None`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub block: Option<u32>,
    /// Byte offset in the file where it was found, when known; left out of the JSON when `None`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub offset: Option<u64>,
}

fn code_str<S: serde::Serializer>(c: &Code, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_str(c.as_str())
}

impl Issue {
    /// The issue a reader error stands for, with its code, block and offset (the file name is
    /// dropped: the report names the file once).
    pub fn from_error(e: &Error) -> Issue {
        Issue {
            code: e.code(),
            severity: e.code().severity(),
            message: e.kind.to_string(),
            block: e.block,
            offset: e.offset,
        }
    }
}

impl std::fmt::Display for Issue {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let sev = match self.severity {
            Severity::Error => "error",
            Severity::Warning => "warning",
            Severity::Info => "info",
        };
        write!(f, "{sev}[{}]", self.code)?;
        if let Some(b) = self.block {
            write!(f, " block {b}")?;
        }
        if let Some(o) = self.offset {
            write!(f, " byte {o}")?;
        }
        write!(f, ": {}", self.message)
    }
}

/// How much of the file `verify` checks (spec §13); each depth includes the ones before it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Depth {
    /// Header, trailer, directory and metadata only; no block is read.
    Quick,
    /// The default: also reads every block, checks its CRC, decompresses it and checks its
    /// framing and records.
    Full,
    /// Also checks the tree's meaning: the root, every reference, levels, cells, counts.
    Deep,
}

/// The outcome of one `verify` run, serialised as the versioned JSON report.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Report {
    /// Always [`REPORT_SCHEMA`], so a consumer can tell the layout it is reading.
    pub schema: &'static str,
    /// The file's name as the caller gave it to [`verify`](super::verify).
    pub file: String,
    /// The depth the file was checked at.
    pub depth: Depth,
    /// True when no issue of severity error was found (warnings and infos allowed).
    pub valid: bool,
    /// Issues of severity error, omitted ones included.
    pub errors: u64,
    /// Issues of severity warning, omitted ones included.
    pub warnings: u64,
    /// Issues of severity info, omitted ones included.
    pub infos: u64,
    /// At most `max_issues` issues, in the order found.
    pub issues: Vec<Issue>,
    /// Issues found beyond `max_issues`.
    pub issues_omitted: u64,
    /// The file identity, when the trailer could be read.
    pub identity: Option<String>,
    /// Blocks read, decompressed and surveyed without a problem (0 at quick depth).
    pub blocks_checked: u64,
    /// Stored (compressed) bytes of those blocks.
    pub stored_bytes_checked: u64,
    /// Raw (decompressed) bytes of those blocks.
    pub raw_bytes_checked: u64,
}

impl Report {
    pub(crate) fn new(file: &str, depth: Depth) -> Report {
        Report {
            schema: REPORT_SCHEMA,
            file: file.to_string(),
            depth,
            valid: true,
            errors: 0,
            warnings: 0,
            infos: 0,
            issues: Vec::new(),
            issues_omitted: 0,
            identity: None,
            blocks_checked: 0,
            stored_bytes_checked: 0,
            raw_bytes_checked: 0,
        }
    }

    pub(crate) fn push(&mut self, issue: Issue, max_issues: usize) {
        match issue.severity {
            Severity::Error => {
                self.errors += 1;
                self.valid = false;
            }
            Severity::Warning => self.warnings += 1,
            Severity::Info => self.infos += 1,
        }
        if self.issues.len() < max_issues {
            self.issues.push(issue);
        } else {
            self.issues_omitted += 1;
        }
    }

    /// Whether some issue has this code (tests use it).
    pub fn has(&self, code: Code) -> bool {
        self.issues.iter().any(|i| i.code == code)
    }
}
