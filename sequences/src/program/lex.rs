//! The tokens the four program readers share: identifiers, numbers, quoted strings, punctuation
//! and line ends, each with its 1-based line and character column. A comment runs from the
//! format's comment character to the end of the line. Linear in the text; never fails except on
//! an unterminated string.

use crate::Error;

/// What a token is.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum Kind {
    /// Letters, digits, `_` and a leading `$` (KRL system variables), not starting with a digit.
    Ident(String),
    /// A finite decimal number without sign (`12`, `1.5`, `.5`, `9E9`, `9E+09`).
    Number(f64),
    /// A quoted string (`"…"` or `'…'`), without the quotes.
    Str(String),
    /// One punctuation character, or `:=`, `==`, `<>`, `<=`, `>=`.
    Punct(&'static str),
    /// Any other character (refused by every parser that meets it).
    Other(char),
    /// The end of a line.
    Newline,
}

/// A token and where it starts.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Tok {
    pub kind: Kind,
    pub line: usize,
    pub column: usize,
}

impl Tok {
    pub fn error(&self, message: impl Into<String>) -> Error {
        Error::at(self.line, self.column, message)
    }

    /// The token as shown in a message.
    pub fn shown(&self) -> String {
        match &self.kind {
            Kind::Ident(s) => format!("`{s}`"),
            Kind::Number(v) => format!("`{}`", crate::error::shown(*v)),
            Kind::Str(s) => format!("the string \"{}\"", s.chars().take(40).collect::<String>()),
            Kind::Punct(p) => format!("`{p}`"),
            Kind::Other(c) => format!("`{}`", c.escape_default()),
            Kind::Newline => "the end of the line".into(),
        }
    }

    pub fn is_ident(&self, word: &str) -> bool {
        matches!(&self.kind, Kind::Ident(s) if s.eq_ignore_ascii_case(word))
    }

    pub fn is_punct(&self, p: &str) -> bool {
        matches!(&self.kind, Kind::Punct(q) if *q == p)
    }
}

const PUNCT: &[&str] = &[
    ":=", "==", "<>", "<=", ">=", "[", "]", "{", "}", "(", ")", ",", ";", ":", "=", ".", "+", "-",
    "*", "/", "\\", "%", "#", "&", "<", ">", "!", "@", "^", "|", "?", "~",
];

/// Tokens of `text`, lines counted from `first_line`; `comment` starts a comment (outside
/// strings). Strings do not cross lines.
pub(crate) fn lex(text: &str, first_line: usize, comment: Option<char>) -> Result<Vec<Tok>, Error> {
    let mut out = Vec::new();
    for (k, line) in text.split('\n').enumerate() {
        let line_no = first_line + k;
        let chars: Vec<(usize, char)> = line.char_indices().collect();
        let mut i = 0;
        while i < chars.len() {
            let (at, c) = chars[i];
            let column = i + 1;
            let tok = |kind| Tok {
                kind,
                line: line_no,
                column,
            };
            if Some(c) == comment {
                break;
            }
            if c.is_whitespace() {
                i += 1;
                continue;
            }
            if c.is_ascii_alphabetic() || c == '_' || c == '$' {
                let mut j = i + 1;
                while j < chars.len() && (chars[j].1.is_ascii_alphanumeric() || chars[j].1 == '_') {
                    j += 1;
                }
                let end = chars.get(j).map_or(line.len(), |c| c.0);
                out.push(tok(Kind::Ident(line[at..end].to_string())));
                i = j;
                continue;
            }
            if c.is_ascii_digit()
                || (c == '.' && chars.get(i + 1).is_some_and(|d| d.1.is_ascii_digit()))
            {
                let mut j = i;
                while j < chars.len() && chars[j].1.is_ascii_digit() {
                    j += 1;
                }
                if j < chars.len() && chars[j].1 == '.' {
                    j += 1;
                    while j < chars.len() && chars[j].1.is_ascii_digit() {
                        j += 1;
                    }
                }
                if j < chars.len() && matches!(chars[j].1, 'e' | 'E') {
                    let mut e = j + 1;
                    if e < chars.len() && matches!(chars[e].1, '+' | '-') {
                        e += 1;
                    }
                    if e < chars.len() && chars[e].1.is_ascii_digit() {
                        while e < chars.len() && chars[e].1.is_ascii_digit() {
                            e += 1;
                        }
                        j = e;
                    }
                }
                let end = chars.get(j).map_or(line.len(), |c| c.0);
                let text = &line[at..end];
                match text.parse::<f64>() {
                    Ok(v) if v.is_finite() => out.push(tok(Kind::Number(v))),
                    _ => {
                        return Err(Error::at(
                            line_no,
                            column,
                            format!("`{text}` is not a finite number"),
                        ));
                    }
                }
                i = j;
                continue;
            }
            if c == '"' || c == '\'' {
                let mut j = i + 1;
                while j < chars.len() && chars[j].1 != c {
                    j += 1;
                }
                if j >= chars.len() {
                    return Err(Error::at(
                        line_no,
                        column,
                        "the string is not closed on its line",
                    ));
                }
                let s: String = chars[i + 1..j].iter().map(|c| c.1).collect();
                out.push(tok(Kind::Str(s)));
                i = j + 1;
                continue;
            }
            let rest = &line[at..];
            if let Some(p) = PUNCT.iter().find(|p| rest.starts_with(**p)) {
                out.push(tok(Kind::Punct(p)));
                i += p.chars().count();
                continue;
            }
            out.push(tok(Kind::Other(c)));
            i += 1;
        }
        out.push(Tok {
            kind: Kind::Newline,
            line: line_no,
            column: chars.len() + 1,
        });
    }
    Ok(out)
}

/// A cursor over tokens with the expectations every parser makes.
#[derive(Debug)]
pub(crate) struct Cursor<'a> {
    pub toks: &'a [Tok],
    pub pos: usize,
}

impl<'a> Cursor<'a> {
    pub fn new(toks: &'a [Tok]) -> Self {
        Cursor { toks, pos: 0 }
    }

    /// The current token (the last, a line end, once past the end).
    pub fn peek(&self) -> &'a Tok {
        &self.toks[self.pos.min(self.toks.len() - 1)]
    }

    pub fn peek_at(&self, k: usize) -> &'a Tok {
        &self.toks[(self.pos + k).min(self.toks.len() - 1)]
    }

    pub fn at_end(&self) -> bool {
        self.pos >= self.toks.len()
    }

    pub fn next(&mut self) -> &'a Tok {
        let t = self.peek();
        self.pos += 1;
        t
    }

    pub fn skip_newlines(&mut self) {
        while !self.at_end() && self.peek().kind == Kind::Newline {
            self.pos += 1;
        }
    }

    pub fn eat_punct(&mut self, p: &str) -> bool {
        if self.peek().is_punct(p) && !self.at_end() {
            self.pos += 1;
            true
        } else {
            false
        }
    }

    pub fn eat_ident(&mut self, word: &str) -> bool {
        if self.peek().is_ident(word) && !self.at_end() {
            self.pos += 1;
            true
        } else {
            false
        }
    }

    pub fn expect_punct(&mut self, p: &str) -> Result<(), Error> {
        if self.eat_punct(p) {
            Ok(())
        } else {
            let t = self.peek();
            Err(t.error(format!("expected `{p}`, found {}", t.shown())))
        }
    }

    pub fn expect_ident_word(&mut self, word: &str) -> Result<(), Error> {
        if self.eat_ident(word) {
            Ok(())
        } else {
            let t = self.peek();
            Err(t.error(format!("expected `{word}`, found {}", t.shown())))
        }
    }

    pub fn ident(&mut self) -> Result<(String, &'a Tok), Error> {
        let t = self.peek();
        match &t.kind {
            Kind::Ident(s) if !self.at_end() => {
                self.pos += 1;
                Ok((s.clone(), t))
            }
            _ => Err(t.error(format!("expected a name, found {}", t.shown()))),
        }
    }

    pub fn newline(&mut self) -> Result<(), Error> {
        let t = self.peek();
        if t.kind == Kind::Newline {
            self.pos += 1;
            Ok(())
        } else {
            Err(t.error(format!("expected the end of the line, found {}", t.shown())))
        }
    }

    /// A signed number (`-` or `+` in front allowed).
    pub fn number(&mut self) -> Result<f64, Error> {
        let t = self.peek();
        let sign = if self.eat_punct("-") {
            -1.0
        } else {
            self.eat_punct("+");
            1.0
        };
        let n = self.peek();
        match n.kind {
            Kind::Number(v) if !self.at_end() => {
                self.pos += 1;
                Ok(sign * v)
            }
            _ => Err(n.error(format!(
                "expected a number, found {}",
                if std::ptr::eq(t, n) {
                    t.shown()
                } else {
                    n.shown()
                }
            ))),
        }
    }

    /// A non-negative integer that fits `u32`.
    pub fn integer(&mut self) -> Result<u32, Error> {
        let t = self.peek();
        match t.kind {
            Kind::Number(v) if !self.at_end() && v.fract() == 0.0 && (0.0..=4e9).contains(&v) => {
                self.pos += 1;
                Ok(v as u32)
            }
            _ => Err(t.error(format!("expected a whole number, found {}", t.shown()))),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tokens_carry_lines_and_columns() {
        let t = lex("MoveL p1, v100 \\T:=2.5; ! note\n  x := 9E9", 1, Some('!')).unwrap();
        assert_eq!(t[0].kind, Kind::Ident("MoveL".into()));
        assert_eq!(t[4].kind, Kind::Punct("\\"));
        assert_eq!(t[6].kind, Kind::Punct(":="));
        assert_eq!(t[7].kind, Kind::Number(2.5));
        assert_eq!(t[9].kind, Kind::Newline);
        assert_eq!((t[10].line, t[10].column), (2, 3));
        assert_eq!(t[12].kind, Kind::Number(9e9));
        assert!(lex("'open", 1, None).is_err());
    }
}
