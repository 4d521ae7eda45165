//! Errors are values: every failure a user can cause (bad scene file, missing mesh,
//! absurd parameter) becomes an [`Error`] naming the file, the line and what was expected.

use std::path::PathBuf;

/// Where in an input file a problem was found. `line`/`column` are 1-based; 0 means unknown.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Location {
    pub file: PathBuf,
    pub line: usize,
    pub column: usize,
}

impl std::fmt::Display for Location {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match (self.line, self.column) {
            (0, _) => write!(f, "{}", self.file.display()),
            (l, 0) => write!(f, "{}:{}", self.file.display(), l),
            (l, c) => write!(f, "{}:{}:{}", self.file.display(), l, c),
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// Input that does not parse or does not make sense, with its location.
    #[error("{location}: {message}")]
    Input { location: Location, message: String },
    /// A parameter outside its allowed range (command line or API).
    #[error("invalid {what}: {message}")]
    Parameter { what: String, message: String },
    /// Image encoding failed.
    #[error("{path}: cannot write image: {message}")]
    Image { path: PathBuf, message: String },
}

impl Error {
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }

    pub fn input(
        file: impl Into<PathBuf>,
        line: usize,
        column: usize,
        message: impl Into<String>,
    ) -> Self {
        Error::Input {
            location: Location {
                file: file.into(),
                line,
                column,
            },
            message: message.into(),
        }
    }

    pub fn parameter(what: impl Into<String>, message: impl Into<String>) -> Self {
        Error::Parameter {
            what: what.into(),
            message: message.into(),
        }
    }
}

pub type Result<T> = std::result::Result<T, Error>;
