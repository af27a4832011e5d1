//! A progress bar on the terminal for long work; silent when stderr is not a terminal.

use std::ops::ControlFlow;
use std::sync::{Mutex, OnceLock};
use std::time::Duration;

use indicatif::{ProgressBar, ProgressStyle};
use skelform::{Control, Progress};

static BAR: OnceLock<Mutex<Option<(ProgressBar, &'static str)>>> = OnceLock::new();

fn slot() -> &'static Mutex<Option<(ProgressBar, &'static str)>> {
    BAR.get_or_init(|| Mutex::new(None))
}

/// A control that draws a bar per phase when `show` is set.
pub fn control(show: bool) -> Control {
    if !show {
        return Control::default();
    }
    Control::with_callback(|p: &Progress| {
        let Ok(mut guard) = slot().lock() else { return ControlFlow::Continue(()) };
        let fresh = !matches!(&*guard, Some((_, phase)) if *phase == p.phase);
        if fresh {
            if let Some((bar, _)) = guard.take() {
                bar.finish_and_clear();
            }
            // A known total gets a bar; work whose size is not known until it ends (the
            // propagating polygonizers visit cubes until the surface closes) a counter.
            let (bar, template) = match p.total {
                Some(total) => {
                    (ProgressBar::new(total), "{msg:>12} [{bar:40}] {pos}/{len} {elapsed}")
                }
                None => {
                    (ProgressBar::no_length(), "{msg:>12} {spinner} {human_pos} cubes {elapsed}")
                }
            };
            let style = ProgressStyle::with_template(template)
                .unwrap_or_else(|_| ProgressStyle::default_bar());
            bar.set_style(style.progress_chars("=> "));
            bar.set_message(p.phase);
            bar.enable_steady_tick(Duration::from_millis(200));
            *guard = Some((bar, p.phase));
        }
        if let Some((bar, _)) = &*guard {
            bar.set_position(p.done);
        }
        ControlFlow::Continue(())
    })
}

/// Clears the bar.
pub fn finish() {
    if let Ok(mut guard) = slot().lock()
        && let Some((bar, _)) = guard.take()
    {
        bar.finish_and_clear();
    }
}
