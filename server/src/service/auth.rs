//! Bearer tokens and roles.
//!
//! A tokens file (TOML) lists who may do what:
//!
//! ```toml
//! [[tokens]]
//! token = "s3cret-instructor"
//! role = "instructor"          # observe any session, create and close sessions
//! name = "Dr. Example"
//!
//! [[tokens]]
//! token = "s3cret-station-1"
//! role = "trainee"             # join as a station, claim only its instruments
//!                              # (a station with none only watches: instructors)
//! instruments = ["left"]       # absent: any instrument
//! ```
//!
//! Every call carries `authorization: Bearer <token>`; an unknown or missing token is
//! `UNAUTHENTICATED`, a role without the right is `PERMISSION_DENIED`. Without a
//! tokens file (a loopback server for one person) every caller is an instructor.
//! Both roles may list recordings and replay finished ones (review); a recording
//! still being made is a live session, which only an instructor may watch.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use laparo_proto::text::printable;

use super::limits::{MAX_INSTRUMENTS, MAX_NAME_BYTES};
use serde::Deserialize;
use tonic::{Request, Status};

use crate::engine::scene::{FileError, read_bounded};

/// What a caller may do.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Role {
    Trainee,
    Instructor,
}

/// The caller of a request, as its token says.
#[derive(Clone, Debug, PartialEq)]
pub struct Caller {
    pub name: String,
    pub role: Role,
    /// Instruments a trainee may claim; `None`: any.
    pub instruments: Option<Vec<String>>,
}

impl Caller {
    /// Everyone, on a server without tokens.
    pub fn open() -> Self {
        Caller {
            name: "anonymous".into(),
            role: Role::Instructor,
            instruments: None,
        }
    }

    /// `PERMISSION_DENIED` unless the caller is an instructor.
    pub fn require_instructor(&self, what: &str) -> Result<(), Status> {
        match self.role {
            Role::Instructor => Ok(()),
            Role::Trainee => Err(Status::permission_denied(format!(
                "{what} needs an instructor token; `{}` is a trainee",
                self.name
            ))),
        }
    }

    /// Whether the caller may claim `instrument`.
    pub fn may_claim(&self, instrument: &str) -> bool {
        self.instruments
            .as_ref()
            .is_none_or(|list| list.iter().any(|i| i == instrument))
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct TokensFile {
    tokens: Vec<TokenEntry>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct TokenEntry {
    token: String,
    role: Role,
    #[serde(default)]
    name: Option<String>,
    #[serde(default)]
    instruments: Option<Vec<String>>,
}

/// What is wrong with a list of tokens; `tokens[k]` counts entries from 0.
#[derive(Debug, thiserror::Error)]
pub enum TokenListError {
    /// The file is not the TOML of a tokens list: where, and what is wrong,
    /// without the line itself, which may hold a token.
    #[error("line {line}, column {column}: {message}")]
    Toml {
        line: usize,
        column: usize,
        message: String,
    },
    #[error("tokens[{index}].token: at most {MAX_TOKEN_BYTES} bytes (is {len})")]
    TooLong { index: usize, len: usize },
    #[error("tokens[{index}].{field}: at most {MAX_NAME_BYTES} bytes (is {len})")]
    NameTooLong {
        index: usize,
        field: &'static str,
        len: usize,
    },
    #[error("tokens[{index}].instruments: at most {MAX_INSTRUMENTS} (is {len})")]
    TooManyInstruments { index: usize, len: usize },
    #[error("tokens[{index}].token: at least 8 characters")]
    TooShort { index: usize },
    #[error(
        "tokens[{index}].token: visible ASCII only (no spaces, control characters or \
         non-ASCII letters: clients could not send it)"
    )]
    NotVisibleAscii { index: usize },
    #[error("no tokens: a server with an empty list would refuse every call")]
    Empty,
    #[error("tokens[{index}].token: listed twice")]
    Twice { index: usize },
}

/// A tokens file that cannot be used; each names the file.
#[derive(Debug, thiserror::Error)]
pub enum TokensError {
    #[error("{} {source}", path.display())]
    Read { path: PathBuf, source: FileError },
    #[error("{}: {source}", path.display())]
    Invalid {
        path: PathBuf,
        source: TokenListError,
    },
}

/// Largest tokens file read, bytes: 1 MiB, some ten thousand tokens.
pub const MAX_TOKENS_BYTES: u64 = 1 << 20;

/// Longest token, bytes: 1 KiB holds any random secret many times over, and a
/// longer one would be refused by the HTTP/2 header limits before it is read.
pub const MAX_TOKEN_BYTES: usize = 1024;

/// [`TokenListError::Toml`] for `e`, read from `text`: toml's own rendering quotes
/// the offending line, token and all, into the server's log; where it is and what
/// is wrong suffice to mend it.
fn toml_error(text: &str, e: &toml::de::Error) -> TokenListError {
    let (line, column) = e.span().map_or((0, 0), |span| {
        let before = &text[..text.floor_char_boundary(span.start)];
        let line_start = before.rfind('\n').map_or(0, |i| i + 1);
        (
            before.matches('\n').count() + 1,
            before[line_start..].chars().count() + 1,
        )
    });
    TokenListError::Toml {
        line,
        column,
        message: e.message().trim_end().to_string(),
    }
}

/// The tokens a server accepts.
#[derive(Clone, Debug, Default)]
pub struct Tokens {
    by_token: HashMap<String, Caller>,
}

impl Tokens {
    /// Reads a tokens file (a regular file of at most [`MAX_TOKENS_BYTES`]); errors
    /// name the file and what is wrong.
    pub fn load(path: &Path) -> Result<Self, TokensError> {
        let read = |source| TokensError::Read {
            path: path.to_path_buf(),
            source,
        };
        let bytes = read_bounded(path, None, MAX_TOKENS_BYTES).map_err(read)?;
        let text = String::from_utf8(bytes).map_err(|e| {
            read(FileError::Io(std::io::Error::other(format!(
                "not UTF-8: {e}"
            ))))
        })?;
        Self::parse(&text).map_err(|source| TokensError::Invalid {
            path: path.to_path_buf(),
            source,
        })
    }

    /// Reads the text of a tokens file: at least one token, every token at least 8
    /// characters of visible ASCII (what an `authorization` header carries and
    /// clients send: a space, a control character or a non-ASCII letter would make
    /// a token no client can present) and listed once.
    pub fn parse(text: &str) -> Result<Self, TokenListError> {
        let file: TokensFile = toml::from_str(text).map_err(|e| toml_error(text, &e))?;
        if file.tokens.is_empty() {
            return Err(TokenListError::Empty);
        }
        let mut by_token = HashMap::new();
        for (k, t) in file.tokens.into_iter().enumerate() {
            if !t.token.bytes().all(|b| b.is_ascii_graphic()) {
                return Err(TokenListError::NotVisibleAscii { index: k });
            }
            if t.token.len() < 8 {
                return Err(TokenListError::TooShort { index: k });
            }
            if t.token.len() > MAX_TOKEN_BYTES {
                let len = t.token.len();
                return Err(TokenListError::TooLong { index: k, len });
            }
            // A name travels in statuses (gRPC's `grpc-message` header), events
            // and the recording: held to the limit of every other name.
            let long = |field, len| TokenListError::NameTooLong {
                index: k,
                field,
                len,
            };
            if let Some(name) = t.name.as_ref().filter(|n| n.len() > MAX_NAME_BYTES) {
                return Err(long("name", name.len()));
            }
            let instruments = t.instruments.as_deref().unwrap_or_default();
            if instruments.len() > MAX_INSTRUMENTS {
                let len = instruments.len();
                return Err(TokenListError::TooManyInstruments { index: k, len });
            }
            if let Some(i) = instruments.iter().find(|i| i.len() > MAX_NAME_BYTES) {
                return Err(long("instruments", i.len()));
            }
            // The name is only ever shown (in refusals, events and logs), so it is
            // kept escaped: a control character in the operator's file reaches no
            // client's terminal as it is.
            let name = t.name.unwrap_or_else(|| format!("tokens[{k}]"));
            let caller = Caller {
                name: printable(&name).into_owned(),
                role: t.role,
                instruments: t.instruments,
            };
            if by_token.insert(t.token, caller).is_some() {
                return Err(TokenListError::Twice { index: k });
            }
        }
        Ok(Tokens { by_token })
    }

    /// A token for tests and tools.
    pub fn insert(&mut self, token: &str, caller: Caller) {
        self.by_token.insert(token.to_string(), caller);
    }
}

/// The interceptor every service runs: puts the [`Caller`] in the request's
/// extensions.
#[derive(Clone)]
pub struct Authenticate {
    tokens: Option<Arc<Tokens>>,
}

impl Authenticate {
    pub fn new(tokens: Option<Tokens>) -> Self {
        Authenticate {
            tokens: tokens.map(Arc::new),
        }
    }
}

impl tonic::service::Interceptor for Authenticate {
    fn call(&mut self, mut request: Request<()>) -> Result<Request<()>, Status> {
        let caller = match &self.tokens {
            None => Caller::open(),
            Some(tokens) => {
                let header = request.metadata().get("authorization").ok_or_else(|| {
                    Status::unauthenticated("missing `authorization: Bearer <token>`")
                })?;
                let token = header
                    .to_str()
                    .ok()
                    .and_then(|h| h.strip_prefix("Bearer "))
                    .ok_or_else(|| {
                        Status::unauthenticated("authorization must be `Bearer <token>`")
                    })?;
                tokens
                    .by_token
                    .get(token.trim())
                    .cloned()
                    .ok_or_else(|| Status::unauthenticated("unknown token"))?
            }
        };
        request.extensions_mut().insert(caller);
        Ok(request)
    }
}

/// The caller the interceptor found (every service is built with it; a request
/// without one is refused rather than let through).
pub fn caller<T>(request: &Request<T>) -> Result<Caller, Status> {
    request
        .extensions()
        .get::<Caller>()
        .cloned()
        .ok_or_else(|| Status::internal("the request was not authenticated"))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn entry(token: &str) -> String {
        format!("[[tokens]]\ntoken = {token:?}\nrole = \"trainee\"\n")
    }

    #[test]
    fn a_token_no_client_could_send_is_refused_by_its_place() {
        assert!(Tokens::parse(&entry("a-long-random-string")).is_ok());
        for bad in [
            " leading-space",
            "trailing-space ",
            "in side-space",
            "line\nbreak-1",
            "naïve-token-é",
        ] {
            let text = entry("a-long-random-string") + &entry(bad);
            let e = Tokens::parse(&text).unwrap_err();
            assert!(
                matches!(e, TokenListError::NotVisibleAscii { index: 1 }),
                "{bad:?}: {e}"
            );
            assert!(
                e.to_string().starts_with("tokens[1].token: visible ASCII"),
                "{e}"
            );
        }
        assert!(matches!(
            Tokens::parse(&entry("short")).unwrap_err(),
            TokenListError::TooShort { index: 0 }
        ));
    }

    #[test]
    fn a_name_is_kept_escaped_for_the_refusals_that_show_it() {
        let text = format!(
            "{}name = \"Bob \\u001b[31mred\\u202e\"\n",
            entry("a-long-random-string")
        );
        let tokens = Tokens::parse(&text).unwrap();
        let caller = tokens.by_token.get("a-long-random-string").unwrap();
        let e = caller.require_instructor("creating a session").unwrap_err();
        assert_eq!(
            e.message(),
            "creating a session needs an instructor token; `Bob \\u{1b}[31mred\\u{202e}` is a trainee"
        );
    }

    #[test]
    fn names_and_tokens_past_their_limits_are_refused_naming_them() {
        let ok = entry("a-long-random-string");
        let named = |name: &str| format!("{ok}name = {name:?}\n");
        assert!(Tokens::parse(&named(&"n".repeat(MAX_NAME_BYTES))).is_ok());
        let e = Tokens::parse(&named(&"n".repeat(MAX_NAME_BYTES + 1))).unwrap_err();
        assert_eq!(e.to_string(), "tokens[0].name: at most 256 bytes (is 257)");
        let e = Tokens::parse(&entry(&"t".repeat(MAX_TOKEN_BYTES + 1))).unwrap_err();
        assert_eq!(
            e.to_string(),
            "tokens[0].token: at most 1024 bytes (is 1025)"
        );
        assert!(Tokens::parse(&entry(&"t".repeat(MAX_TOKEN_BYTES))).is_ok());
        let listed = |names: Vec<String>| format!("{ok}instruments = {names:?}\n");
        let e = Tokens::parse(&listed(vec!["i".repeat(MAX_NAME_BYTES + 1)])).unwrap_err();
        assert_eq!(
            e.to_string(),
            "tokens[0].instruments: at most 256 bytes (is 257)"
        );
        let many = (0..=MAX_INSTRUMENTS).map(|i| format!("i{i}")).collect();
        let e = Tokens::parse(&listed(many)).unwrap_err();
        assert_eq!(e.to_string(), "tokens[0].instruments: at most 64 (is 65)");
    }

    #[test]
    fn a_syntax_error_says_where_without_quoting_the_token() {
        let text = "# tokens\n[[tokens]]\ntoken = \"s3cr3t-instructor-token\" role = \"x\"\n";
        let e = Tokens::parse(text).unwrap_err().to_string();
        assert!(e.starts_with("line 3, column "), "{e}");
        assert!(!e.contains("s3cr3t"), "{e}");
        let e = Tokens::parse("[[tokens]]\ntoken = \"s3cr3t-\\q-token\"\n")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("line 2, column "), "{e}");
        assert!(!e.contains("s3cr3t"), "{e}");
    }

    #[test]
    fn an_empty_list_is_refused() {
        let e = Tokens::parse("tokens = []").unwrap_err();
        assert!(matches!(e, TokenListError::Empty), "{e}");
    }

    #[test]
    fn a_tokens_file_must_be_a_bounded_regular_file() {
        let e = Tokens::load(Path::new("/dev/zero")).unwrap_err();
        assert!(
            e.to_string() == "/dev/zero is a character device, not a regular file",
            "{e}"
        );
        let dir = tempfile::tempdir().unwrap();
        let big = dir.path().join("tokens.toml");
        std::fs::write(&big, vec![b'#'; MAX_TOKENS_BYTES as usize + 1]).unwrap();
        let e = Tokens::load(&big).unwrap_err();
        assert!(e.to_string().contains("over the limit"), "{e}");
    }
}
