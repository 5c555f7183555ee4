//! The crate's one error type: a message that names the bad field or file.
//!
//! Errors are values: every check of user input returns
//! `Err(Error)` with a one-line message, the CLI prints it and exits non-zero.

use std::fmt;

/// A one-line, human-readable error naming the field or file at fault.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Error(pub String);

/// Result with the crate's error type.
pub type Result<T> = std::result::Result<T, Error>;

impl Error {
    /// An error with the given message.
    pub fn new(msg: impl Into<String>) -> Self {
        Error(msg.into())
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for Error {}

impl From<std::io::Error> for Error {
    fn from(e: std::io::Error) -> Self {
        Error(e.to_string())
    }
}

/// Characters kept at each end of a long path or value echoed in a message.
pub const SHOWN_ENDS: usize = 60;

/// `text` as it goes into a one-line message: as is up to `2 * SHOWN_ENDS`
/// characters, else its first and last [`SHOWN_ENDS`] characters around an
/// ellipsis (a 50 MB path is not echoed in full); line breaks become spaces.
///
/// ```
/// use dualphoton::error::shorten;
/// assert_eq!(shorten("a/b.npy"), "a/b.npy");
/// let long = "x".repeat(1000);
/// assert_eq!(shorten(&long).chars().count(), 2 * 60 + 3);
/// ```
pub fn shorten(text: &str) -> String {
    let chars: Vec<char> = text.chars().map(|c| if c == '\n' || c == '\r' { ' ' } else { c }).collect();
    if chars.len() <= 2 * SHOWN_ENDS {
        return chars.into_iter().collect();
    }
    let head: String = chars[..SHOWN_ENDS].iter().collect();
    let tail: String = chars[chars.len() - SHOWN_ENDS..].iter().collect();
    format!("{head}...{tail}")
}

/// A path as it goes into a message: [`shorten`]ed.
pub fn show(path: &std::path::Path) -> String {
    shorten(&path.display().to_string())
}

/// Returns `Err` with the formatted message: `bail!("volume.g: {g} is not in (-1, 1)")`.
#[macro_export]
macro_rules! bail {
    ($($arg:tt)*) => { return Err($crate::error::Error(format!($($arg)*))) };
}

/// The exit code of a command-line run: success, or the error printed as
/// one line (`error: ...`) and a failure code.
pub fn exit_code(result: Result<()>) -> std::process::ExitCode {
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            std::process::ExitCode::FAILURE
        }
    }
}
