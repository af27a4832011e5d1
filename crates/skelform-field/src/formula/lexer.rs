//! Splitting formula text into tokens, each with its 1-based line and column (in characters).

use super::FormulaError;

/// A token kind.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum Tok {
    Num(f64),
    Ident(String),
    Plus,
    Minus,
    Star,
    Slash,
    Caret,
    LParen,
    RParen,
    Comma,
    Assign,
    Semi,
    Newline,
    Eof,
    /// A lexical error; the parser reports it when it reaches it, so that errors come out in
    /// the order of the text.
    Error(FormulaError),
}

impl Tok {
    /// How the token reads in an error message ("found ...").
    pub(crate) fn describe(&self) -> String {
        match self {
            Tok::Num(v) => format!("the number {v}"),
            Tok::Ident(s) => format!("'{s}'"),
            Tok::Plus => "'+'".into(),
            Tok::Minus => "'-'".into(),
            Tok::Star => "'*'".into(),
            Tok::Slash => "'/'".into(),
            Tok::Caret => "'^'".into(),
            Tok::LParen => "'('".into(),
            Tok::RParen => "')'".into(),
            Tok::Comma => "','".into(),
            Tok::Assign => "'='".into(),
            Tok::Semi => "';'".into(),
            Tok::Newline => "the end of the line".into(),
            Tok::Eof => "the end of the formula".into(),
            Tok::Error(e) => e.message().to_string(),
        }
    }
}

/// A token and where it starts.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Token {
    pub tok: Tok,
    pub line: usize,
    pub column: usize,
}

/// Tokenises the whole text. The result always ends with `Eof` or with one `Error` token
/// (after which nothing follows).
pub(crate) fn tokenize(text: &str) -> Vec<Token> {
    let chars: Vec<char> = text.chars().collect();
    let mut out = Vec::new();
    let (mut i, mut line, mut column) = (0usize, 1usize, 1usize);
    while i < chars.len() {
        let c = chars[i];
        let start = (line, column);
        let push = |out: &mut Vec<Token>, tok: Tok| {
            out.push(Token { tok, line: start.0, column: start.1 });
        };
        match c {
            '\n' => {
                push(&mut out, Tok::Newline);
                i += 1;
                line += 1;
                column = 1;
                continue;
            }
            '#' => {
                while i < chars.len() && chars[i] != '\n' {
                    i += 1;
                    column += 1;
                }
                continue;
            }
            c if c.is_whitespace() => {}
            '+' => push(&mut out, Tok::Plus),
            '-' => push(&mut out, Tok::Minus),
            '*' => push(&mut out, Tok::Star),
            '/' => push(&mut out, Tok::Slash),
            '^' => push(&mut out, Tok::Caret),
            '(' => push(&mut out, Tok::LParen),
            ')' => push(&mut out, Tok::RParen),
            ',' => push(&mut out, Tok::Comma),
            '=' => push(&mut out, Tok::Assign),
            ';' => push(&mut out, Tok::Semi),
            c if c.is_ascii_digit()
                || (c == '.' && chars.get(i + 1).is_some_and(char::is_ascii_digit)) =>
            {
                let n = number_len(&chars[i..]);
                let lexeme: String = chars[i..i + n].iter().collect();
                match lexeme.parse::<f64>() {
                    Ok(v) if v.is_finite() => push(&mut out, Tok::Num(v)),
                    _ => {
                        let msg = format!("the number '{lexeme}' is too large");
                        push(&mut out, Tok::Error(FormulaError::new(start.0, start.1, msg)));
                        return out;
                    }
                }
                i += n;
                column += n;
                continue;
            }
            c if c.is_ascii_alphabetic() || c == '_' => {
                let n = chars[i..]
                    .iter()
                    .take_while(|c| c.is_ascii_alphanumeric() || **c == '_')
                    .count();
                push(&mut out, Tok::Ident(chars[i..i + n].iter().collect()));
                i += n;
                column += n;
                continue;
            }
            c => {
                let msg = if c == '.' {
                    "unexpected character '.' (a number needs a digit next to its decimal point)"
                        .to_string()
                } else {
                    format!("unexpected character {}", quote_char(c))
                };
                push(&mut out, Tok::Error(FormulaError::new(start.0, start.1, msg)));
                return out;
            }
        }
        i += 1;
        column += 1;
    }
    out.push(Token { tok: Tok::Eof, line, column });
    out
}

/// `'$'`, or the escaped form for control characters.
fn quote_char(c: char) -> String {
    if c.is_control() { format!("'{}'", c.escape_default()) } else { format!("'{c}'") }
}

/// Length of the number starting at `s[0]`: digits, an optional fraction, and an exponent
/// when `e`/`E` is followed by digits (with an optional sign). `2e` is the number `2`
/// followed by the name `e`, which the parser then rejects.
fn number_len(s: &[char]) -> usize {
    let digits = |from: usize| s[from..].iter().take_while(|c| c.is_ascii_digit()).count();
    let mut n = digits(0);
    if s.get(n) == Some(&'.') {
        n += 1;
        n += digits(n);
    }
    if matches!(s.get(n), Some('e' | 'E')) {
        let mut m = n + 1;
        if matches!(s.get(m), Some('+' | '-')) {
            m += 1;
        }
        let d = digits(m);
        if d > 0 {
            n = m + d;
        }
    }
    n
}

#[cfg(test)]
mod tests {
    use super::*;

    fn kinds(s: &str) -> Vec<Tok> {
        tokenize(s).into_iter().map(|t| t.tok).collect()
    }

    #[test]
    fn numbers() {
        assert_eq!(
            kinds("1 0.5 .5 1e-3 2.5E+2 3."),
            vec![
                Tok::Num(1.0),
                Tok::Num(0.5),
                Tok::Num(0.5),
                Tok::Num(1e-3),
                Tok::Num(250.0),
                Tok::Num(3.0),
                Tok::Eof
            ]
        );
        assert_eq!(kinds("2e"), vec![Tok::Num(2.0), Tok::Ident("e".into()), Tok::Eof]);
        assert_eq!(
            kinds("2e+x"),
            vec![
                Tok::Num(2.0),
                Tok::Ident("e".into()),
                Tok::Plus,
                Tok::Ident("x".into()),
                Tok::Eof
            ]
        );
    }

    #[test]
    fn positions_count_characters() {
        let t = tokenize("é = 1");
        assert!(matches!(&t[0].tok, Tok::Error(e) if e.column() == 1 && e.line() == 1));
        let t = tokenize("# café\n  ab = 1 # x\n");
        assert_eq!((t[0].tok.clone(), t[0].line, t[0].column), (Tok::Newline, 1, 7));
        assert_eq!((t[1].tok.clone(), t[1].line, t[1].column), (Tok::Ident("ab".into()), 2, 3));
        assert_eq!((t[2].line, t[2].column), (2, 6));
        assert_eq!(t.last().unwrap().tok, Tok::Eof);
        assert_eq!((t.last().unwrap().line, t.last().unwrap().column), (3, 1));
    }

    #[test]
    fn bad_characters() {
        let t = tokenize("x + $");
        let Tok::Error(e) = &t[2].tok else { panic!("{t:?}") };
        assert_eq!((e.line(), e.column(), e.message()), (1, 5, "unexpected character '$'"));
        let t = tokenize("1e999");
        assert!(matches!(&t[0].tok, Tok::Error(e) if e.message().contains("too large")));
    }
}
