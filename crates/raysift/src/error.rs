//! The library's error type. Every message names the file (or input) and the place in it, so the
//! CLI can print it as one line.

/// Errors from loading, validating or tracing.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// Malformed content: `file`, the place (line, element or byte offset) and what is wrong.
    #[error("{file}: {place}: {msg}")]
    Parse {
        /// File (or input) name.
        file: String,
        /// Where: "line 12", "vertex 7", "byte 1024", ...
        place: String,
        /// What is wrong.
        msg: String,
    },
    /// The file could not be opened, read or written.
    #[error("{file}: {err}")]
    Io {
        /// File name.
        file: String,
        /// The underlying error (shown in the message, so not chained as a source).
        err: std::io::Error,
    },
    /// Invalid argument or configuration (unknown tracer name, bad option, ...).
    #[error("{0}")]
    Invalid(String),
}

impl Error {
    /// Shorthand for [`Error::Parse`].
    pub fn parse(
        file: impl Into<String>,
        place: impl Into<String>,
        msg: impl Into<String>,
    ) -> Self {
        Error::Parse {
            file: file.into(),
            place: place.into(),
            msg: msg.into(),
        }
    }

    /// Shorthand for [`Error::Io`].
    pub fn io(file: impl Into<String>, source: std::io::Error) -> Self {
        Error::Io {
            file: file.into(),
            err: source,
        }
    }
}

/// `Result` with [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;
