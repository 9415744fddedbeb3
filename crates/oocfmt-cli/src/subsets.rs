//! `oocfmt plan`, `oocfmt convert --plan` and `oocfmt merge`: a build split into subsets that
//! separate processes (a batch engine's array tasks) build, then merged into one container.

use std::path::{Path, PathBuf};
use std::sync::atomic::Ordering;

use oocfmt_build::subsets::{
    build_subset, convert_plan, make_plan, merge, plan_of_subset, update_plan, MergeReport, Plan,
    PlanReport, SubsetError, SubsetReport,
};

use crate::args::use_threads;
use crate::build_args::BuildArgs;
use crate::convert::{on_signals, render, write_report_json};
use crate::error::{to_json, CliError, CliResult};
use crate::out::out;
use crate::progress::Phases;

#[derive(clap::Args)]
pub struct PlanArgs {
    /// Input files (.obj, .gltf, .glb, .stl, .ply), as for convert; not `-` (a plan reads
    /// them several times)
    #[arg(required_unless_present = "update", conflicts_with = "update")]
    pub inputs: Vec<PathBuf>,
    /// Subsets to cut the scene into, 1 to 4096 (cells no triangle reaches are dropped, so the
    /// plan may have fewer)
    #[arg(long, required_unless_present = "update", conflicts_with = "update")]
    pub subsets: Option<u32>,
    /// Plan again the inputs of this plan after some changed, with its settings and, where
    /// it can, its cuts: the new plan reuses the subsets no change reaches, and the report
    /// lists those to build again
    #[arg(long, value_name = "OLD_PLAN")]
    pub update: Option<PathBuf>,
    /// The plan to write (JSON)
    #[arg(short, long)]
    pub output: PathBuf,
    #[command(flatten)]
    pub build: BuildArgs,
    /// Print the report as JSON instead of text
    #[arg(long)]
    pub json: bool,
    /// Worker threads (default: all cores)
    #[arg(long)]
    pub threads: Option<usize>,
    /// No progress bars
    #[arg(long)]
    pub quiet: bool,
}

#[derive(clap::Args)]
pub struct MergeArgs {
    /// The subset files (.oocfp) of one plan: every subset once, in any order
    #[arg(required = true)]
    pub parts: Vec<PathBuf>,
    /// The plan to merge for (default: the one the files were built from, or the newest of
    /// them after `plan --update`)
    #[arg(long)]
    pub plan: Option<PathBuf>,
    /// The container to write
    #[arg(short, long)]
    pub output: PathBuf,
    /// Also write the report as JSON to this file
    #[arg(long)]
    pub report_json: Option<PathBuf>,
    /// Worker threads (default: all cores)
    #[arg(long)]
    pub threads: Option<usize>,
    /// No progress bars
    #[arg(long)]
    pub quiet: bool,
}

pub fn run_plan(a: &PlanArgs) -> CliResult {
    use_threads(a.threads)?;
    let old = match &a.update {
        Some(_) if a.build != BuildArgs::defaults()? => {
            return Err(CliError::Usage(
                "with --update the build settings are the old plan's: give no build flag".into(),
            ));
        }
        Some(path) => Some(Plan::read(path)?),
        None => None,
    };
    let build = match &old {
        Some(p) => BuildArgs::from_settings(&p.settings)?,
        None => a.build.clone(),
    };
    let opts = build.options(None)?;
    let signal = on_signals(&opts.interrupt)?;
    let mut progress = Phases::new(a.quiet);
    let made = match (&old, a.subsets) {
        (Some(old), _) => update_plan(old, &opts, &mut progress),
        (None, Some(n)) => make_plan(&a.inputs, n, build.settings(), &opts, &mut progress),
        (None, None) => return Err(CliError::Usage("--subsets is required".into())),
    };
    let (plan, report) = made.map_err(|e| interrupted(e, signal.load(Ordering::Relaxed)))?;
    plan.write(&a.output)?;
    match a.json {
        true => out!("{}", to_json(&report)?)?,
        false => out!("{}", render_plan(&a.output, &report))?,
    }
    Ok(0)
}

fn render_plan(path: &Path, r: &PlanReport) -> String {
    use std::fmt::Write;
    let mut o = String::new();
    let _ = writeln!(
        o,
        "wrote      {} (plan {}): {} subsets ({} asked), {} triangles, {:.2} s",
        path.display(),
        r.identity,
        r.subsets,
        r.asked,
        r.triangles,
        r.seconds
    );
    for (i, n) in r.records.iter().enumerate() {
        let build = match r.rebuild.contains(&(i as u32)) {
            true => "build",
            false => "reuse",
        };
        let _ = writeln!(o, "subset {i:<4} {n} triangle records: {build}");
    }
    if let Some(why) = &r.replanned {
        let _ = writeln!(
            o,
            "replanned  the cuts could not stay ({why}): every subset is built again"
        );
    }
    let list: Vec<String> = r.rebuild.iter().map(u32::to_string).collect();
    let _ = writeln!(
        o,
        "build      {} of {} subsets: {}",
        r.rebuild.len(),
        r.subsets,
        list.join(",")
    );
    o
}

/// `convert --plan PLAN [--subset I]`: the plan's settings, not the command line's.
pub fn convert_planned(a: &crate::convert::Args, plan_path: &Path) -> CliResult {
    if a.build != BuildArgs::defaults()? {
        return Err(CliError::Usage(
            "with --plan the build settings are the plan's: give them to `oocfmt plan`".into(),
        ));
    }
    let plan = Plan::read(plan_path)?;
    let build = BuildArgs::from_settings(&plan.settings)?;
    let opts = build.options(a.tmp_dir.clone())?;
    let signal = on_signals(&opts.interrupt)?;
    let mut progress = Phases::new(a.quiet);
    let stop = |e| interrupted(e, signal.load(Ordering::Relaxed));
    match a.subset {
        Some(i) => {
            let r = build_subset(&plan, i, &a.output, &opts, &mut progress).map_err(stop)?;
            write_report_json(a.report_json.as_deref(), &r)?;
            out!("{}", render_subset(&r))?;
        }
        None => {
            let r = convert_plan(&plan, &a.output, &opts, &mut progress).map_err(stop)?;
            write_report_json(a.report_json.as_deref(), &r)?;
            out!("{}", render(&r))?;
        }
    }
    Ok(0)
}

fn render_subset(r: &SubsetReport) -> String {
    let memory = r.peak_memory_bytes.map_or("unknown".into(), |b| {
        format!("{:.1} MiB", b as f64 / 1048576.0)
    });
    format!(
        "wrote      {} (subset {} of {}: {} bytes)\n\
         built      {} triangle records in {} chunks, {} blocks\n\
         time       {:.2} s\n\
         memory     peak {memory}\n\
         disk       peak {:.1} MiB of spill files\n",
        r.output,
        r.index,
        r.subsets,
        r.file_bytes,
        r.records,
        r.chunks,
        r.blocks,
        r.seconds,
        r.peak_disk_bytes as f64 / 1048576.0
    )
}

pub fn run_merge(a: &MergeArgs) -> CliResult {
    use_threads(a.threads)?;
    let given = a.plan.as_deref().map(Plan::read).transpose()?;
    let plan = match &given {
        Some(p) => p.clone(),
        None => plan_of_subset(a.parts.first().ok_or(SubsetError::NoSubsets)?)?,
    };
    let build = BuildArgs::from_settings(&plan.settings)?;
    let opts = build.options(None)?;
    let signal = on_signals(&opts.interrupt)?;
    let mut progress = Phases::new(a.quiet);
    let r = merge(&a.parts, &a.output, &opts, given.as_ref(), &mut progress)
        .map_err(|e| interrupted(e, signal.load(Ordering::Relaxed)))?;
    write_report_json(a.report_json.as_deref(), &r)?;
    out!("{}", render_merge(&r))?;
    Ok(0)
}

fn render_merge(r: &MergeReport) -> String {
    // The merge reads no model and spills nothing: the import's placement and the disk line
    // would only repeat zeros.
    let convert: String = render(&r.convert)
        .lines()
        .filter(|l| !l.starts_with("positions") && !l.starts_with("disk"))
        .map(|l| format!("{l}\n"))
        .collect();
    format!(
        "{convert}merged     {} subsets: {} blocks ({} raw bytes) copied, references made final; nothing rebuilt\n",
        r.subsets,
        r.copied_blocks,
        r.copied_bytes
    )
}

/// A stop on a signal becomes its exit code (128 + the signal's number).
fn interrupted(e: SubsetError, signal: usize) -> CliError {
    match (&e, u8::try_from(signal)) {
        (SubsetError::Interrupted { .. }, Ok(n @ 1..=127)) => CliError::SubsetsInterrupted {
            code: 128 + n,
            source: e,
        },
        _ => e.into(),
    }
}
