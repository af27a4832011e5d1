//! Diagnostics: from byte offsets in the scene text to `file:line:column: message` errors.
//!
//! The TOML parser gives every value a span (`toml::Spanned`), a range of byte offsets in
//! the file. The code that checks a section knows those offsets but not the file's text or
//! name, so it reports through an [`At`], which [`Source::at`] makes once per file: the
//! checks stay free of bookkeeping, and every message is positioned the same way (1-based
//! lines and columns counted in characters, as editors count them).
//!
//! Formulas are the one place where positions come from elsewhere: a formula's errors are
//! positioned within the formula's text, so [`Source::formula_error`] maps them back into
//! the file, accounting for the quotes (and the line break after `"""`) that open the
//! string.

use skelform_field::formula::FormulaError;

use crate::SceneError;

/// Makes a positioned error from a byte offset in the scene text and a message; how the
/// section checkers report, without knowing the file they check.
pub(crate) type At<'a> = &'a dyn Fn(usize, String) -> SceneError;

/// The text of a scene file and the name it is shown by, for positioning errors.
pub(crate) struct Source<'a> {
    pub(crate) text: &'a str,
    pub(crate) origin: &'a str,
}

impl Source<'_> {
    /// The error for `message` at byte `offset` of the text. Line breaks in the message
    /// (from a value it quotes, such as a name) are shown as `\n`, so that every error
    /// stays on one line.
    pub(crate) fn at(&self, offset: usize, message: impl Into<String>) -> SceneError {
        let (line, column) = line_col(self.text, offset);
        let message = one_line(message.into());
        SceneError::At { path: self.origin.to_string(), line, column, message }
    }

    /// A TOML syntax or schema error (unknown key, wrong type), on one line, with serde's
    /// Rust type names replaced by plain words.
    pub(crate) fn toml_error(&self, e: &toml::de::Error) -> SceneError {
        let offset = e.span().map_or(0, |s| s.start);
        self.at(offset, plain_types(e.message().trim_end()).replace('\n', "; "))
    }

    /// A formula's error, positioned in the file: `literal` is the byte offset where the
    /// formula's TOML string starts (its opening quote). A position the message cites
    /// ("opened at line 2, column 5") is translated the same way.
    pub(crate) fn formula_error(&self, literal: usize, e: &FormulaError) -> SceneError {
        let content = content_start(self.text, literal);
        let (line0, col0) = line_col(self.text, content);
        // Formula positions to file positions: the first line starts at the content's column.
        let to_file =
            |l: usize, c: usize| if l == 1 { (line0, col0 + c - 1) } else { (line0 + l - 1, c) };
        let (line, column) = to_file(e.line(), e.column());
        SceneError::At {
            path: self.origin.to_string(),
            line,
            column,
            message: e.message_mapped(to_file),
        }
    }
}

/// 1-based line and column (in characters) of a byte offset; an offset past the end, or
/// inside a character, counts as the end or that character.
pub(crate) fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let offset = offset.min(text.len());
    let before = &text[..text.floor_char_boundary(offset)];
    let line = before.matches('\n').count() + 1;
    let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, col)
}

/// `message` with its line breaks written as `\n` and `\r`.
fn one_line(message: String) -> String {
    if message.contains(['\n', '\r']) {
        message.replace('\n', "\\n").replace('\r', "\\r")
    } else {
        message
    }
}

/// serde names Rust types in its messages; say what they mean instead.
fn plain_types(message: &str) -> String {
    message
        .replace("expected i64", "expected a whole number")
        .replace("expected f64", "expected a number")
        .replace("expected a sequence", "expected an array")
        .replace("expected an array of length 3", "expected an array of three numbers")
}

/// Byte offset where a TOML string's content starts, given where its literal starts.
fn content_start(text: &str, literal: usize) -> usize {
    let rest = &text[literal.min(text.len())..];
    let skip = if rest.starts_with("\"\"\"") || rest.starts_with("'''") {
        let after = &rest[3..];
        3 + if after.starts_with("\r\n") {
            2
        } else if after.starts_with('\n') {
            1
        } else {
            0
        }
    } else if rest.starts_with('"') || rest.starts_with('\'') {
        1
    } else {
        0
    };
    literal + skip
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn line_col_counts_characters_from_one() {
        let text = "ab\nçd\n";
        assert_eq!(line_col(text, 0), (1, 1));
        assert_eq!(line_col(text, 3), (2, 1));
        // 'ç' is two bytes: the 'd' after it is the second character.
        assert_eq!(line_col(text, 5), (2, 2));
        // Inside 'ç', and past the end.
        assert_eq!(line_col(text, 4), (2, 1));
        assert_eq!(line_col(text, 100), (3, 1));
    }

    #[test]
    fn content_starts_after_the_quotes() {
        let text = "f = \"\"\"\nx\"\"\"\ng = 'y'";
        assert_eq!(content_start(text, 4), 8);
        assert_eq!(content_start(text, 17), 18);
    }
}
