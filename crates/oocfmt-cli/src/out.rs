//! Standard output for reports. A closed stdout (`oocfmt inspect F | head`) is not an error:
//! the reader took what it wanted, so the rest is dropped and the command still succeeds; any
//! other write failure (a full disk behind a redirect) is reported.

use std::io::Write;

use crate::error::CliError;

pub fn write(args: std::fmt::Arguments<'_>) -> Result<(), CliError> {
    match std::io::stdout().lock().write_fmt(args) {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => Err(CliError::Io {
            path: "standard output".into(),
            source: e,
        }),
        _ => Ok(()),
    }
}

/// `print!` through [`write`]: `out!(...)?`.
macro_rules! out {
    ($($arg:tt)*) => { $crate::out::write(format_args!($($arg)*)) };
}

/// `println!` through [`write`]: `outln!(...)?`.
macro_rules! outln {
    () => { $crate::out::write(format_args!("\n")) };
    ($($arg:tt)*) => { $crate::out::write(format_args!("{}\n", format_args!($($arg)*))) };
}

pub(crate) use {out, outln};
