//! The verify report: issues with stable codes, and the versioned JSON schema around them.

use serde::Serialize;

use crate::error::{Code, Error, Severity};

/// The report schema's name and version; bump the number on any incompatible change.
pub const REPORT_SCHEMA: &str = "oocfmt-verify/1";

#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Issue {
    #[serde(serialize_with = "code_str")]
    pub code: Code,
    pub severity: Severity,
    pub message: String,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub block: Option<u32>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub offset: Option<u64>,
}

fn code_str<S: serde::Serializer>(c: &Code, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_str(c.as_str())
}

impl Issue {
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

#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Depth {
    Quick,
    Full,
    Deep,
}

#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct Report {
    pub schema: &'static str,
    pub file: String,
    pub depth: Depth,
    pub valid: bool,
    pub errors: u64,
    pub warnings: u64,
    pub infos: u64,
    /// At most `max_issues` issues, in the order found.
    pub issues: Vec<Issue>,
    /// Issues found beyond `max_issues`.
    pub issues_omitted: u64,
    /// The file identity, when the trailer could be read.
    pub identity: Option<String>,
    pub blocks_checked: u64,
    pub stored_bytes_checked: u64,
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
