//! Progress bars for long work, shown only on a terminal.

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// A byte progress bar; hidden when stderr is not a terminal or `quiet` is set.
pub fn bytes(total: u64, label: &str, quiet: bool) -> ProgressBar {
    let bar = ProgressBar::new(total);
    if quiet {
        bar.set_draw_target(ProgressDrawTarget::hidden());
    }
    let style = ProgressStyle::with_template(
        "{msg} [{bar:40}] {bytes}/{total_bytes} {bytes_per_sec} eta {eta}",
    )
    .map(|s| s.progress_chars("=> "))
    .unwrap_or_else(|_| ProgressStyle::default_bar());
    bar.set_style(style);
    bar.set_message(label.to_string());
    bar
}

/// The library's phase progress, drawn as one bar (or spinner) per phase on stderr.
pub struct Phases {
    bar: Option<ProgressBar>,
    quiet: bool,
}

impl Phases {
    pub fn new(quiet: bool) -> Self {
        Phases { bar: None, quiet }
    }
}

impl oocfmt_build::progress::Progress for Phases {
    fn phase(&mut self, name: &str, total: Option<u64>) {
        let bar = match total {
            Some(t) => {
                let b = ProgressBar::new(t);
                let style =
                    ProgressStyle::with_template("{msg:>14} [{bar:40}] {pos}/{len} eta {eta}")
                        .map(|s| s.progress_chars("=> "))
                        .unwrap_or_else(|_| ProgressStyle::default_bar());
                b.set_style(style);
                b
            }
            None => {
                let b = ProgressBar::new_spinner();
                b.enable_steady_tick(std::time::Duration::from_millis(120));
                b
            }
        };
        if self.quiet {
            bar.set_draw_target(ProgressDrawTarget::hidden());
        }
        bar.set_message(name.to_string());
        self.bar = Some(bar);
    }

    fn advance(&mut self, done: u64) {
        if let Some(b) = &self.bar {
            b.set_position(done);
        }
    }

    fn finish_phase(&mut self) {
        if let Some(b) = self.bar.take() {
            b.finish_and_clear();
        }
    }

    /// On stderr at once (above the bar, if one is drawn), even with `--quiet`.
    fn warn(&mut self, message: &str) {
        let line = || eprintln!("warning    {message}");
        match &self.bar {
            Some(b) => b.suspend(line),
            None => line(),
        }
    }
}

/// A counting bar whose total the work sets as it learns it.
pub fn count(label: &str, quiet: bool) -> ProgressBar {
    let bar = ProgressBar::new(0);
    if quiet {
        bar.set_draw_target(ProgressDrawTarget::hidden());
    }
    let style = ProgressStyle::with_template("{msg:>10} [{bar:40}] {pos}/{len} eta {eta}")
        .map(|s| s.progress_chars("=> "))
        .unwrap_or_else(|_| ProgressStyle::default_bar());
    bar.set_style(style);
    bar.set_message(label.to_string());
    bar
}
