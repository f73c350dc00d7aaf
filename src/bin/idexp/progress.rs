//! Progress bars: the command line's [`Observer`]. One bar per phase, drawn
//! on standard error; hidden when `IDEXP_NO_PROGRESS` is set or standard
//! error is not a terminal. Notes are printed above the bar.

use idexp::optim::Observer;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::io::IsTerminal;
use std::sync::Mutex;

/// indicatif progress bars behind [`Observer`].
pub struct Bars {
    /// The current phase's bar (None between phases).
    bar: Mutex<Option<ProgressBar>>,
    /// Draw at all (terminal and no `IDEXP_NO_PROGRESS`).
    visible: bool,
}

impl Bars {
    /// Bars drawn on standard error when it is a terminal and `IDEXP_NO_PROGRESS` is unset.
    pub fn new() -> Bars {
        Bars {
            bar: Mutex::new(None),
            visible: std::env::var_os("IDEXP_NO_PROGRESS").is_none() && std::io::stderr().is_terminal(),
        }
    }

    fn with_bar(&self, f: impl FnOnce(&ProgressBar)) {
        if let Ok(g) = self.bar.lock() {
            if let Some(b) = g.as_ref() {
                f(b);
            }
        }
    }
}

impl Observer for Bars {
    fn phase(&self, name: &str, total: Option<u64>) {
        let pb = match total {
            Some(n) => ProgressBar::new(n),
            None => ProgressBar::new_spinner(),
        };
        if self.visible {
            // redrawn four times a second: the elapsed time and the spinner
            // stay live through a long step (a check of a long trajectory)
            pb.enable_steady_tick(std::time::Duration::from_millis(250));
        } else {
            pb.set_draw_target(ProgressDrawTarget::hidden());
        }
        let template = if total.is_some() {
            "{prefix} [{elapsed_precise}] {bar:30} {pos}/{len} {msg}"
        } else {
            "{prefix} [{elapsed_precise}] {spinner} {pos} {msg}"
        };
        if let Ok(style) = ProgressStyle::with_template(template) {
            pb.set_style(style);
        }
        pb.set_prefix(name.to_string());
        if let Ok(mut g) = self.bar.lock() {
            if let Some(old) = g.replace(pb) {
                old.finish_and_clear();
            }
        }
    }

    fn progress(&self, done: u64, msg: &str) {
        self.with_bar(|b| {
            b.set_position(done);
            if !msg.is_empty() {
                b.set_message(msg.to_string());
            }
        });
    }

    fn phase_done(&self) {
        if let Ok(mut g) = self.bar.lock() {
            if let Some(b) = g.take() {
                b.finish_and_clear();
            }
        }
    }

    fn note(&self, msg: &str) {
        let mut shown = false;
        if self.visible {
            self.with_bar(|b| {
                b.println(msg);
                shown = true;
            });
        }
        if !shown {
            eprintln!("{msg}");
        }
    }
}
