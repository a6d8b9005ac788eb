//! AFF tokens: whitespace-separated words with their file, line and column,
//! across include files.
//!
//! Lines may end in CRLF or LF; `#` and `%` start comments that run to the end
//! of the line (also after a command); bytes are read as Latin-1, so comments
//! in any 8-bit encoding are harmless.

use std::path::{Path, PathBuf};
use std::rc::Rc;

use crate::SceneError;
use crate::limits::{MAX_INCLUDE_DEPTH, MAX_INCLUDES, read_file};

/// One word of the input.
#[derive(Clone, Debug)]
pub(crate) struct Token {
    pub text: String,
    pub file: Rc<PathBuf>,
    pub line: usize,
    pub col: usize,
}

/// Splits a file's bytes into tokens.
pub(crate) fn tokenize(bytes: &[u8], file: &Rc<PathBuf>) -> Vec<Token> {
    // Latin-1: every byte is one char.
    let text: String = bytes.iter().map(|&b| b as char).collect();
    let mut out = Vec::new();
    for (i, raw) in text.split('\n').enumerate() {
        let line = raw.strip_suffix('\r').unwrap_or(raw);
        let line = line.find(['#', '%']).map_or(line, |c| &line[..c]);
        let mut col = 0usize;
        for word in line.split([' ', '\t', '\r', '\x0c', '\x0b']) {
            // Braces are tokens of their own even when written against a word.
            let mut start = 0usize;
            let chars: Vec<char> = word.chars().collect();
            let mut push = |from: usize, to: usize| {
                if to > from {
                    out.push(Token {
                        text: chars[from..to].iter().collect(),
                        file: Rc::clone(file),
                        line: i + 1,
                        col: col + from + 1,
                    });
                }
            };
            for (k, &c) in chars.iter().enumerate() {
                if c == '{' || c == '}' {
                    push(start, k);
                    push(k, k + 1);
                    start = k + 1;
                }
            }
            push(start, chars.len());
            col += chars.len() + 1;
        }
    }
    out
}

/// A stack of token streams: the main file and the files it includes.
pub(crate) struct TokenStream {
    stack: Vec<(Vec<Token>, usize)>,
    /// The last token handed out (for errors at end of input).
    last: Option<Token>,
    root: PathBuf,
    /// Include files pushed so far.
    includes: usize,
}

impl TokenStream {
    pub fn open(path: &Path) -> Result<Self, SceneError> {
        let mut s = Self {
            stack: Vec::new(),
            last: None,
            root: path.to_path_buf(),
            includes: 0,
        };
        s.push_file(path)?;
        Ok(s)
    }

    /// Pushes an included file; its tokens come next.
    pub fn push_file(&mut self, path: &Path) -> Result<(), SceneError> {
        if self.stack.len() >= MAX_INCLUDE_DEPTH {
            return Err(self.error_at_last(format!(
                "includes nest deeper than {MAX_INCLUDE_DEPTH} files (MAX_INCLUDE_DEPTH; an include cycle?) at {}",
                path.display()
            )));
        }
        if self.includes > MAX_INCLUDES {
            return Err(self.error_at_last(format!(
                "more than {MAX_INCLUDES} includes (MAX_INCLUDES) at {}",
                path.display()
            )));
        }
        self.includes += 1;
        let bytes = read_file(path)?;
        let file = Rc::new(path.to_path_buf());
        self.stack.push((tokenize(&bytes, &file), 0));
        Ok(())
    }

    /// Tokens not handed out yet, in all open files.
    pub fn remaining(&self) -> usize {
        self.stack.iter().map(|(toks, pos)| toks.len() - pos).sum()
    }

    /// The capacity to reserve for `n` items read from here: never more than
    /// the tokens left, since every item takes at least one.
    pub fn capacity_for(&self, n: usize) -> usize {
        n.min(self.remaining())
    }

    pub fn peek(&mut self) -> Option<&Token> {
        while let Some((toks, pos)) = self.stack.last() {
            if *pos < toks.len() {
                break;
            }
            self.stack.pop();
        }
        let (toks, pos) = self.stack.last()?;
        toks.get(*pos)
    }

    pub fn next(&mut self) -> Option<Token> {
        self.peek()?;
        let (toks, pos) = self.stack.last_mut()?;
        let t = toks[*pos].clone();
        *pos += 1;
        self.last = Some(t.clone());
        Some(t)
    }

    /// A parse error at `tok`.
    pub fn error(tok: &Token, msg: impl Into<String>) -> SceneError {
        SceneError::Parse {
            path: (*tok.file).clone(),
            line: tok.line,
            col: tok.col,
            msg: msg.into(),
        }
    }

    /// A parse error just after the last token (end of input).
    pub fn error_at_last(&self, msg: impl Into<String>) -> SceneError {
        match &self.last {
            Some(t) => SceneError::Parse {
                path: (*t.file).clone(),
                line: t.line,
                col: t.col + t.text.chars().count(),
                msg: msg.into(),
            },
            None => SceneError::Parse {
                path: self.root.clone(),
                line: 1,
                col: 1,
                msg: msg.into(),
            },
        }
    }

    /// The next token, or an error saying what was expected.
    pub fn expect(&mut self, what: &str) -> Result<Token, SceneError> {
        match self.next() {
            Some(t) => Ok(t),
            None => Err(self.error_at_last(format!("file ends where {what} was expected"))),
        }
    }

    /// A finite number.
    pub fn number(&mut self, what: &str) -> Result<f32, SceneError> {
        let t = self.expect(what)?;
        match t.text.parse::<f32>() {
            Ok(v) if v.is_finite() => Ok(v),
            Ok(_) => Err(Self::error(&t, format!("{what}: '{}' is not a finite number", t.text))),
            Err(_) => Err(Self::error(
                &t,
                format!("expected {what} (a number), found '{}'", t.text),
            )),
        }
    }

    /// Three finite numbers.
    pub fn vec3(&mut self, what: &str) -> Result<glam::Vec3, SceneError> {
        Ok(glam::Vec3::new(
            self.number(what)?,
            self.number(what)?,
            self.number(what)?,
        ))
    }

    /// A count (non-negative integer) no larger than `limit`.
    pub fn count(&mut self, what: &str, limit: usize) -> Result<usize, SceneError> {
        let t = self.expect(what)?;
        match t.text.parse::<usize>() {
            Ok(v) if v <= limit => Ok(v),
            Ok(v) => Err(Self::error(&t, format!("{what} {v} exceeds the limit of {limit}"))),
            Err(_) => Err(Self::error(
                &t,
                format!("expected {what} (a whole number), found '{}'", t.text),
            )),
        }
    }

    /// `true` if the next token is on the same line as `tok` and parses as a number.
    pub fn number_follows_on_line(&mut self, tok: &Token) -> bool {
        let line = tok.line;
        let file = Rc::clone(&tok.file);
        self.peek()
            .is_some_and(|n| n.line == line && Rc::ptr_eq(&n.file, &file) && n.text.parse::<f32>().is_ok())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn comments_crlf_tabs_and_latin1() {
        let file = Rc::new(PathBuf::from("t.aff"));
        let bytes = b"fm 1\t2 3 # comment \xe9\xe8\r\n% whole line\r\n  x name{\n";
        let t = tokenize(bytes, &file);
        let words: Vec<&str> = t.iter().map(|t| t.text.as_str()).collect();
        assert_eq!(words, ["fm", "1", "2", "3", "x", "name", "{"]);
        assert_eq!((t[4].line, t[4].col), (3, 3));
        assert_eq!((t[2].line, t[2].col), (1, 6));
    }
}
