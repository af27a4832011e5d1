//! Standard output and error that never panic: `println!` panics when the reader has gone
//! (`skelform check --json X | head -1`) or the disk is full (`> /dev/full`).
//!
//! A closed pipe ends the command quietly with success, as ripgrep does: the reader took all
//! it wanted. Any other failure to write the results is a runtime failure (exit 1) that says
//! so. Messages on standard error are best effort: there is nowhere to report their failure.

use std::fmt;
use std::io::{self, Write};

use anyhow::anyhow;

use crate::Failure;

/// Writes to standard output; a closed pipe or a write error becomes a [`Failure`].
pub fn out(args: fmt::Arguments<'_>) -> Result<(), Failure> {
    to_stdout(|w| w.write_fmt(args))
}

/// Writes bytes (a mesh) to standard output, with the same handling of failure as [`out`].
pub fn out_bytes(bytes: &[u8]) -> Result<(), Failure> {
    to_stdout(|w| w.write_all(bytes))
}

/// Runs `write` on standard output and flushes it, turning failure into a [`Failure`].
fn to_stdout(
    write: impl FnOnce(&mut io::StdoutLock<'static>) -> io::Result<()>,
) -> Result<(), Failure> {
    let mut stdout = io::stdout().lock();
    write(&mut stdout).and_then(|()| stdout.flush()).map_err(|e| match e.kind() {
        io::ErrorKind::BrokenPipe => Failure::quiet(),
        _ => Failure { code: 1, error: Some(anyhow!("cannot write to standard output: {e}")) },
    })
}

/// Writes to standard error, ignoring failure.
pub fn err(args: fmt::Arguments<'_>) {
    let _ = io::stderr().lock().write_fmt(args);
}

/// `println!` that returns a [`Failure`] from the enclosing function instead of panicking.
macro_rules! outln {
    ($($arg:tt)*) => {
        $crate::console::out(format_args!("{}\n", format_args!($($arg)*)))?
    };
}

/// `print!` that returns a [`Failure`] from the enclosing function instead of panicking.
macro_rules! outp {
    ($($arg:tt)*) => {
        $crate::console::out(format_args!($($arg)*))?
    };
}

/// `eprintln!` that never panics.
macro_rules! errln {
    ($($arg:tt)*) => {
        $crate::console::err(format_args!("{}\n", format_args!($($arg)*)))
    };
}
