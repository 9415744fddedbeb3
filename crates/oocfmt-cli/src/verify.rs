//! `oocfmt verify`.

use std::path::PathBuf;

use oocfmt::verify::{verify, Depth, VerifyOptions};
use oocfmt::{ByteSource, FileSource};

use crate::error::{to_json, CliError, CliResult};
use crate::out::outln;
use crate::progress;

#[derive(clap::Args)]
pub struct Args {
    /// The container to check
    pub file: PathBuf,
    /// Header, trailer, directory and metadata only
    #[arg(long, conflicts_with = "deep")]
    pub quick: bool,
    /// Also check the tree's meaning: references, bounds, radii, counts
    #[arg(long)]
    pub deep: bool,
    /// Keep at most this many issues in the report (the rest are counted)
    #[arg(long, default_value_t = 1000)]
    pub max_issues: usize,
    /// Print the report as JSON (schema oocfmt-verify/1)
    #[arg(long)]
    pub json: bool,
    /// No progress bar
    #[arg(long)]
    pub quiet: bool,
}

pub fn run(a: &Args) -> CliResult {
    let depth = if a.quick {
        Depth::Quick
    } else if a.deep {
        Depth::Deep
    } else {
        Depth::Full
    };
    let src = FileSource::open(&a.file).map_err(|e| CliError::Io {
        path: a.file.display().to_string(),
        source: e,
    })?;
    let bar = progress::bytes(src.len(), "verify", a.quiet || a.json);
    let opts = VerifyOptions {
        depth,
        max_issues: a.max_issues,
        ..VerifyOptions::default()
    };
    let name = a.file.display().to_string();
    let report = verify(&src, &name, &opts, &|done| bar.set_position(done))?;
    bar.finish_and_clear();
    if a.json {
        outln!("{}", to_json(&report)?)?;
    } else {
        for issue in &report.issues {
            outln!("{issue}")?;
        }
        if report.issues_omitted > 0 {
            outln!(
                "... {} more issues not shown (raise --max-issues)",
                report.issues_omitted
            )?;
        }
        let verdict = if report.valid { "valid" } else { "INVALID" };
        outln!(
            "{name}: {verdict} ({:?} check): {} errors, {} warnings, {} notes; {} blocks, {} stored bytes checked{}",
            report.depth,
            report.errors,
            report.warnings,
            report.infos,
            report.blocks_checked,
            report.stored_bytes_checked,
            report.identity.as_deref().map(|i| format!("; identity {i}")).unwrap_or_default()
        )?;
    }
    Ok(if report.valid { 0 } else { 1 })
}
