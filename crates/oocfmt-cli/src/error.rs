//! The CLI's errors and the exit codes they map to; the only place errors become exit codes.

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
    Build(String),
}

impl CliError {
    pub fn exit_code(&self) -> u8 {
        match self {
            CliError::Format(e)
                if e.code() == oocfmt::Code::Io || e.code() == oocfmt::Code::InvalidParameter =>
            {
                2
            }
            CliError::Format(_) | CliError::Build(_) => 1,
            CliError::Usage(_) | CliError::Io { .. } => 2,
        }
    }
}

pub type CliResult = Result<u8, CliError>;

pub fn to_json<T: serde::Serialize>(value: &T) -> Result<String, CliError> {
    serde_json::to_string_pretty(value)
        .map_err(|e| CliError::Usage(format!("JSON output failed: {e}")))
}
