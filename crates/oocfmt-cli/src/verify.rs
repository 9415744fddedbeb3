//! `oocfmt verify`.

use std::path::PathBuf;

use oocfmt::verify::{verify, Depth, VerifyOptions};
use oocfmt::{ByteSource, FileSource};

use crate::error::{to_json, CliError, CliResult};
use crate::out::outln;
use crate::progress;

#[derive(clap::Args)]
pub struct Args {
    /// The container to check (or a subset file of `convert --plan P --subset I`)
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
    if oocfmt_build::subsets::is_subset_file(&a.file) {
        return run_subset(a);
    }
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

/// A subset file (`oocfmt convert --plan P --subset I`): its header, body, plan and blocks.
fn run_subset(a: &Args) -> CliResult {
    let name = a.file.display().to_string();
    let checked = oocfmt_build::subsets::verify_subset(&a.file);
    if a.json {
        let v = match &checked {
            Ok(c) => {
                serde_json::json!({"schema": "oocfmt-verify-subset/1", "file": name, "valid": true, "subset": c})
            }
            Err(e) => {
                serde_json::json!({"schema": "oocfmt-verify-subset/1", "file": name, "valid": false, "error": e.to_string()})
            }
        };
        outln!("{}", to_json(&v)?)?;
    } else {
        match &checked {
            Ok(c) => outln!(
                "{name}: valid subset file: subset {} of {} of plan {}; {} blocks, {} bytes checked",
                c.index,
                c.subsets,
                c.plan,
                c.blocks,
                c.block_bytes
            )?,
            Err(e) => {
                outln!("error: {e}")?;
                outln!("{name}: INVALID subset file")?;
            }
        }
    }
    Ok(if checked.is_ok() { 0 } else { 1 })
}
