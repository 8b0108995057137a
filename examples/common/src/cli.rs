//! The examples' command lines, on one small parser (`lexopt`): every example declares its
//! usage text and matches its arguments; an unknown flag or a bad value prints the usage and
//! exits 2, `--help` prints it and exits 0 — before any window opens.
//!
//! ```ignore
//! let mut parser = cli::Parser::from_env();
//! while let Some(arg) = cli::next(&mut parser, USAGE) {
//!     match arg {
//!         cli::Arg::Long("frames") => frames = cli::value(&mut parser, USAGE),
//!         other => cli::unexpected(other, USAGE),
//!     }
//! }
//! ```

#![allow(dead_code)] // each example uses the helpers it needs

use std::path::{Path, PathBuf};
use std::str::FromStr;

pub use lexopt::{Arg, Parser};

/// The next argument; `--help` / `-h` prints `usage` and exits 0, a malformed argument exits 2.
pub fn next<'a>(parser: &'a mut Parser, usage: &str) -> Option<Arg<'a>> {
    match parser.next() {
        Ok(Some(Arg::Long("help") | Arg::Short('h'))) => {
            println!("{usage}");
            std::process::exit(0);
        }
        Ok(arg) => arg,
        Err(e) => fail(e, usage),
    }
}

/// The value after the current flag, parsed as `T` (exits 2 with the usage when it is missing
/// or does not parse).
pub fn value<T: FromStr>(parser: &mut Parser, usage: &str) -> T
where
    T::Err: std::fmt::Display,
{
    parse_as(string(parser, usage), usage)
}

/// The value after the current flag, as text.
pub fn string(parser: &mut Parser, usage: &str) -> String {
    match parser.value().map(|v| v.into_string()) {
        Ok(Ok(s)) => s,
        Ok(Err(v)) => fail(format!("{v:?} is not UTF-8"), usage),
        Err(e) => fail(e, usage),
    }
}

/// A positional argument as text.
pub fn positional(value: std::ffi::OsString, usage: &str) -> String {
    value
        .into_string()
        .unwrap_or_else(|v| fail(format!("{v:?} is not UTF-8"), usage))
}

/// A positional argument parsed as `T` (exits 2 with the usage when it does not parse).
pub fn parse_positional<T: FromStr>(value: std::ffi::OsString, usage: &str) -> T
where
    T::Err: std::fmt::Display,
{
    parse_as(positional(value, usage), usage)
}

/// `text` parsed as `T` (exits 2 with the usage when it does not parse).
fn parse_as<T: FromStr>(text: String, usage: &str) -> T
where
    T::Err: std::fmt::Display,
{
    text.parse()
        .unwrap_or_else(|e: T::Err| fail(format!("{text:?}: {e}"), usage))
}

/// Refuses an argument no branch took: prints why and the usage, exits 2.
pub fn unexpected(arg: Arg<'_>, usage: &str) -> ! {
    fail(arg.unexpected(), usage)
}

/// Prints `error` and the usage, exits 2.
pub fn fail(error: impl std::fmt::Display, usage: &str) -> ! {
    eprintln!("error: {error}\n\n{usage}");
    std::process::exit(2);
}

/// An optional word after a flag (`--remote emulated`, `--pointer emulated`): takes the next
/// argument only when it is `word`, else leaves it for the loop.
pub fn optional_word(parser: &mut Parser, word: &str) -> bool {
    // lexopt hands out `--flag=word` as an optional value; a separate word is peeked at.
    if let Some(v) = parser.optional_value() {
        return v == word;
    }
    let mut raw = match parser.try_raw_args() {
        Some(raw) => raw,
        None => return false,
    };
    if raw.peek().is_some_and(|v| v == word) {
        raw.next();
        return true;
    }
    false
}

/// A model path as a user types it, made loadable by Bevy's asset server (whose root is the
/// project's `assets/` folder; unapproved paths must be allowed): one relative to `assets/`
/// (`models/Fox.glb`) stays as it is; one relative to the working directory or absolute, when
/// the file is there, becomes absolute.
pub fn asset_path(user: &str) -> String {
    if project_dir().join("assets").join(user).is_file() {
        return user.to_string();
    }
    std::fs::canonicalize(user)
        .ok()
        .filter(|p| p.is_file())
        .map(|p| p.to_string_lossy().into_owned())
        .unwrap_or_else(|| user.to_string())
}

/// The file behind an asset path of [`asset_path`] (absolute, or relative to `assets/`).
pub fn asset_file(asset_path: &str) -> PathBuf {
    let path = Path::new(asset_path);
    if path.is_absolute() {
        path.to_path_buf()
    } else {
        project_dir().join("assets").join(path)
    }
}

/// The folder whose `assets/` Bevy's asset server reads, as Bevy finds it: `BEVY_ASSET_ROOT`
/// or `CARGO_MANIFEST_DIR` at run time (set by `cargo run`), else the project this example was
/// built from (this crate lives two folders below it).
fn project_dir() -> PathBuf {
    std::env::var_os("BEVY_ASSET_ROOT")
        .or_else(|| std::env::var_os("CARGO_MANIFEST_DIR"))
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../.."))
}

/// The optional value of `--remote` / `--pointer` / `--emulate`: nothing (real controllers:
/// `None`), `emulated` (an emulated Wii Remote) or `emulated=KIND` — `wiimote`, `dualsense`,
/// `dualsense-edge`, `ds4`, `switch-pro`, `joycon-l`, `joycon-r` (`joycon` = `joycon-r`).
/// `bare` is what the flag means on its own (`--emulate` alone is emulated). A bad kind
/// exits 2.
pub fn emulated_controller(
    parser: &mut Parser,
    bare: Option<bevy_wii_deform::controllers::ControllerKind>,
    usage: &str,
) -> Option<bevy_wii_deform::controllers::ControllerKind> {
    use bevy_wii_deform::controllers::ControllerKind;
    let word = match parser.optional_value() {
        Some(v) => Some(positional(v, usage)),
        None => parser.try_raw_args().and_then(|mut raw| {
            let next = raw.peek()?.to_str()?.to_string();
            (next == "emulated" || next.starts_with("emulated=")).then(|| {
                raw.next();
                next
            })
        }),
    };
    let Some(word) = word else {
        return bare;
    };
    let kind = word.strip_prefix("emulated").unwrap_or(&word);
    let kind = kind.strip_prefix('=').unwrap_or(kind);
    if kind.is_empty() {
        return Some(ControllerKind::WiiRemote);
    }
    Some(
        ControllerKind::from_name(kind)
            .unwrap_or_else(|| fail(format!("unknown controller {kind:?}"), usage)),
    )
}
