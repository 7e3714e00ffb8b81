//! What a long command tells a person while it works, on standard error: on a terminal a
//! bar with the step, the share done and the time left; elsewhere (a log, CI) one line per
//! step with the time since the start, so a reader of the log sees it move too.

use std::io::IsTerminal;
use std::sync::Mutex;
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// How the progress is shown.
enum Shown {
    /// `--quiet`: nothing.
    Nothing,
    /// A terminal: the bar.
    Bar(ProgressBar),
    /// Not a terminal: a line per new step, after the last step's text.
    Lines { last: Mutex<String> },
}

/// Progress and messages of one command.
pub(crate) struct Progress {
    shown: Shown,
    start: Instant,
}

impl Progress {
    /// Progress on standard error: a bar on a terminal, lines elsewhere, nothing if `quiet`.
    pub(crate) fn new(quiet: bool) -> Self {
        let shown = if quiet {
            Shown::Nothing
        } else if std::io::stderr().is_terminal() {
            let bar = ProgressBar::with_draw_target(Some(0), ProgressDrawTarget::stderr());
            bar.set_style(
                ProgressStyle::with_template(
                    "{spinner} [{elapsed_precise}] {wide_msg}\n  {bar:40} {percent:>3} %  ETA {eta}",
                )
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
            );
            bar.enable_steady_tick(Duration::from_millis(120));
            Shown::Bar(bar)
        } else {
            Shown::Lines {
                last: Mutex::new(String::new()),
            }
        };
        Progress {
            shown,
            start: Instant::now(),
        }
    }

    /// A step without a measure of how far it is.
    pub(crate) fn stage(&self, step: &str) {
        self.step(step, None);
    }

    /// A step, and `(done, total)` of the whole command's work when known.
    pub(crate) fn step(&self, step: &str, work: Option<(u64, u64)>) {
        match &self.shown {
            Shown::Nothing => {}
            Shown::Bar(bar) => {
                if let Some((done, total)) = work {
                    bar.set_length(total.max(1));
                    bar.set_position(done.min(total));
                }
                bar.set_message(step.to_string());
            }
            Shown::Lines { last } => {
                let mut last = last.lock().unwrap_or_else(|e| e.into_inner());
                if *last != step {
                    let share = work
                        .map(|(d, t)| format!("{:>3} %  ", 100 * d.min(t) / t.max(1)))
                        .unwrap_or_default();
                    eprintln!(
                        "[{:>7.1} s] {share}{step}",
                        self.start.elapsed().as_secs_f64()
                    );
                    step.clone_into(&mut last);
                }
            }
        }
    }

    /// A message line (not a step): printed above the bar, or as it is.
    pub(crate) fn say(&self, line: &str) {
        match &self.shown {
            Shown::Nothing => {}
            Shown::Bar(bar) => bar.suspend(|| eprintln!("{line}")),
            Shown::Lines { .. } => eprintln!("{line}"),
        }
    }

    /// The work is over: the bar goes.
    pub(crate) fn done(&self) {
        if let Shown::Bar(bar) = &self.shown {
            bar.finish_and_clear();
        }
    }
}
