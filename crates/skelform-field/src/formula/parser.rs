//! Recursive-descent parser that emits nodes straight into the [`Builder`].
//!
//! Grammar (statements are separated by new lines or `;`):
//!
//! ```text
//! formula   := statement (sep statement)*
//! statement := NAME '=' expr | expr
//! expr      := term (('+' | '-') term)*
//! term      := unary (('*' | '/') unary)*
//! unary     := ('-' | '+') unary | power
//! power     := atom ('^' unary)?
//! atom      := NUMBER | NAME | NAME '(' expr (',' expr)* ')' | '(' expr ')'
//! ```

use std::collections::HashMap;

use super::FormulaError;
use super::compile::{Builder, Id};
use super::lexer::{Tok, Token, tokenize};
use super::ops::{BinOp, UnOp};

/// Deepest nesting of parentheses, calls, unary operators and exponents. Keeps the parser's
/// recursion (and so its stack use) bounded on any input.
pub(crate) const MAX_DEPTH: usize = 100;

/// A built-in function.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Func {
    Un(UnOp),
    Bin(BinOp),
    /// `min`/`max`-like: two or more arguments folded from the left.
    Fold(BinOp),
    Clamp,
    Mix,
    Difference,
    SmoothUnion,
    SmoothIntersection,
    SmoothDifference,
}

impl Func {
    /// `(fewest, most)` arguments; `most = None` for any number.
    fn arity(self) -> (usize, Option<usize>) {
        match self {
            Func::Un(_) => (1, Some(1)),
            Func::Bin(_) | Func::Difference => (2, Some(2)),
            Func::Fold(_) => (2, None),
            Func::Clamp
            | Func::Mix
            | Func::SmoothUnion
            | Func::SmoothIntersection
            | Func::SmoothDifference => (3, Some(3)),
        }
    }
}

/// Every function name, aliases included.
const FUNCTIONS: &[(&str, Func)] = &[
    ("abs", Func::Un(UnOp::Abs)),
    ("sqrt", Func::Un(UnOp::Sqrt)),
    ("exp", Func::Un(UnOp::Exp)),
    ("ln", Func::Un(UnOp::Ln)),
    ("log", Func::Un(UnOp::Ln)),
    ("sin", Func::Un(UnOp::Sin)),
    ("cos", Func::Un(UnOp::Cos)),
    ("tan", Func::Un(UnOp::Tan)),
    ("asin", Func::Un(UnOp::Asin)),
    ("acos", Func::Un(UnOp::Acos)),
    ("atan", Func::Un(UnOp::Atan)),
    ("floor", Func::Un(UnOp::Floor)),
    ("sign", Func::Un(UnOp::Sign)),
    ("atan2", Func::Bin(BinOp::Atan2)),
    ("pow", Func::Bin(BinOp::Pow)),
    ("hypot", Func::Bin(BinOp::Hypot)),
    ("min", Func::Fold(BinOp::Min)),
    ("max", Func::Fold(BinOp::Max)),
    ("union", Func::Fold(BinOp::Min)),
    ("intersection", Func::Fold(BinOp::Max)),
    ("difference", Func::Difference),
    ("clamp", Func::Clamp),
    ("mix", Func::Mix),
    ("lerp", Func::Mix),
    ("smooth_union", Func::SmoothUnion),
    ("smin", Func::SmoothUnion),
    ("smooth_intersection", Func::SmoothIntersection),
    ("smax", Func::SmoothIntersection),
    ("smooth_difference", Func::SmoothDifference),
];

fn function(name: &str) -> Option<Func> {
    FUNCTIONS.iter().find(|(n, _)| *n == name).map(|(_, f)| *f)
}

/// Names of the variables and constants.
const VARIABLES: &[&str] = &["x", "y", "z"];
const CONSTANTS: &[(&str, f64)] = &[("pi", std::f64::consts::PI), ("e", std::f64::consts::E)];

/// Whether `name` is a variable, constant or function name.
pub(crate) fn is_reserved(name: &str) -> bool {
    VARIABLES.contains(&name)
        || CONSTANTS.iter().any(|(n, _)| *n == name)
        || function(name).is_some()
}

/// Whether `name` could be written in a formula.
pub(crate) fn is_identifier(name: &str) -> bool {
    let mut chars = name.chars();
    chars.next().is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_')
}

/// What a user name stands for.
#[derive(Clone, Copy, Debug)]
enum Binding {
    Definition { id: Id, line: usize, column: usize },
    Parameter(Id),
}

struct Parser {
    toks: Vec<Token>,
    pos: usize,
    /// Open parentheses: while positive, new lines are skipped.
    paren: usize,
    depth: usize,
    b: Builder,
    names: HashMap<String, Binding>,
    /// Names in the order they were bound, for suggestions.
    order: Vec<String>,
    /// The name whose definition is being parsed.
    defining: Option<String>,
}

type Result<T> = std::result::Result<T, FormulaError>;

/// Parses `text` into nodes; returns the builder and the node of the last statement.
pub(crate) fn parse(text: &str, constants: &[(&str, f64)]) -> Result<(Builder, Id)> {
    let mut p = Parser {
        toks: tokenize(text),
        pos: 0,
        paren: 0,
        depth: 0,
        b: Builder::new(),
        names: HashMap::new(),
        order: Vec::new(),
        defining: None,
    };
    for &(name, value) in constants {
        let bad = |why: &str| Err(FormulaError::new(1, 1, format!("parameter '{name}' {why}")));
        if !is_identifier(name) {
            return bad(
                "is not a valid name (use letters, digits and '_', not starting with a digit)",
            );
        }
        if is_reserved(name) {
            return bad("is reserved and cannot be defined");
        }
        if p.names.contains_key(name) {
            return bad("is given twice");
        }
        let id = p.b.num(value);
        p.names.insert(name.to_string(), Binding::Parameter(id));
        p.order.push(name.to_string());
    }
    let root = p.formula()?;
    Ok((p.b, root))
}

impl Parser {
    /// The current token, skipping new lines inside parentheses.
    fn peek(&mut self) -> &Token {
        while self.paren > 0 && self.toks[self.pos].tok == Tok::Newline {
            self.pos += 1;
        }
        &self.toks[self.pos]
    }

    fn peek_tok(&mut self) -> &Tok {
        &self.peek().tok
    }

    /// Consumes the current token (never moves past the last one).
    fn bump(&mut self) -> Token {
        let t = self.peek().clone();
        if self.pos + 1 < self.toks.len() {
            self.pos += 1;
        }
        t
    }

    /// Skips new lines (after a binary operator the expression goes on).
    fn skip_newlines(&mut self) {
        while self.toks[self.pos].tok == Tok::Newline {
            self.pos += 1;
        }
    }

    /// An error at the current token; a lexical error there takes precedence.
    fn error_here(&mut self, message: impl Into<String>) -> FormulaError {
        let t = self.peek();
        match &t.tok {
            Tok::Error(e) => e.clone(),
            _ => FormulaError::new(t.line, t.column, message.into()),
        }
    }

    fn enter(&mut self) -> Result<()> {
        self.depth += 1;
        if self.depth > MAX_DEPTH {
            return Err(self.error_here(format!(
                "the expression is nested too deeply (more than {MAX_DEPTH} levels)"
            )));
        }
        Ok(())
    }

    fn leave(&mut self) {
        self.depth -= 1;
    }

    fn formula(&mut self) -> Result<Id> {
        // (is_definition, line, column, node) of the statement parsed last.
        let mut last: Option<(bool, usize, usize, Id)> = None;
        loop {
            while matches!(self.peek_tok(), Tok::Newline | Tok::Semi) {
                self.bump();
            }
            let start = self.peek().clone();
            if start.tok == Tok::Eof {
                break;
            }
            if let Some((false, line, column, _)) = last {
                return Err(FormulaError::new(
                    line,
                    column,
                    "only the last statement may be an expression; the ones before it must be \
                     definitions 'name = expression'",
                ));
            }
            let next_is_assign = self.toks.get(self.pos + 1).is_some_and(|t| t.tok == Tok::Assign);
            let statement = match &start.tok {
                Tok::Ident(name) if next_is_assign => {
                    let name = name.clone();
                    self.check_definable(&name, &start)?;
                    self.bump();
                    self.bump();
                    self.skip_newlines();
                    self.defining = Some(name.clone());
                    let id = self.expr()?;
                    self.defining = None;
                    let binding =
                        Binding::Definition { id, line: start.line, column: start.column };
                    self.names.insert(name.clone(), binding);
                    self.order.push(name);
                    (true, start.line, start.column, id)
                }
                _ => (false, start.line, start.column, self.expr()?),
            };
            last = Some(statement);
            match self.peek_tok() {
                Tok::Newline | Tok::Semi | Tok::Eof => {}
                Tok::RParen => return Err(self.error_here("unmatched ')'")),
                Tok::Assign => {
                    return Err(self.error_here(
                        "unexpected '=': a definition is a name, '=', then an expression, on a statement of its own",
                    ));
                }
                other => {
                    let found = other.describe();
                    return Err(self.error_here(format!(
                        "expected an operator, a new line or ';', found {found}"
                    )));
                }
            }
        }
        match last {
            None => Err(FormulaError::new(1, 1, "the formula is empty")),
            Some((true, line, column, _)) => Err(FormulaError::new(
                line,
                column,
                "the last statement must be an expression, not a definition",
            )),
            Some((false, _, _, id)) => Ok(id),
        }
    }

    fn check_definable(&self, name: &str, at: &Token) -> Result<()> {
        let err = |m: String| Err(FormulaError::new(at.line, at.column, m));
        if is_reserved(name) {
            return err(format!("'{name}' is reserved and cannot be defined"));
        }
        match self.names.get(name) {
            Some(Binding::Definition { line, column, .. }) => Err(FormulaError::new(
                at.line,
                at.column,
                format!("'{name}' is already defined (at line {line}, column {column})"),
            )
            .with_related(*line, *column)),
            Some(Binding::Parameter(_)) => {
                err(format!("'{name}' is already defined as a parameter"))
            }
            None => Ok(()),
        }
    }

    fn expr(&mut self) -> Result<Id> {
        self.enter()?;
        let mut lhs = self.term()?;
        loop {
            let op = match self.peek_tok() {
                Tok::Plus => BinOp::Add,
                Tok::Minus => BinOp::Sub,
                _ => break,
            };
            self.bump();
            self.skip_newlines();
            let rhs = self.term()?;
            lhs = self.b.bin(op, lhs, rhs);
        }
        self.leave();
        Ok(lhs)
    }

    fn term(&mut self) -> Result<Id> {
        let mut lhs = self.unary()?;
        loop {
            let op = match self.peek_tok() {
                Tok::Star => BinOp::Mul,
                Tok::Slash => BinOp::Div,
                _ => break,
            };
            self.bump();
            self.skip_newlines();
            let rhs = self.unary()?;
            lhs = self.b.bin(op, lhs, rhs);
        }
        Ok(lhs)
    }

    fn unary(&mut self) -> Result<Id> {
        let negate = match self.peek_tok() {
            Tok::Minus => true,
            Tok::Plus => false,
            _ => return self.power(),
        };
        self.bump();
        self.skip_newlines();
        self.enter()?;
        let a = self.unary()?;
        self.leave();
        Ok(if negate { self.b.un(UnOp::Neg, a) } else { a })
    }

    fn power(&mut self) -> Result<Id> {
        let base = self.atom()?;
        if *self.peek_tok() != Tok::Caret {
            return Ok(base);
        }
        self.bump();
        self.skip_newlines();
        self.enter()?;
        let exponent = self.unary()?;
        self.leave();
        Ok(self.b.bin(BinOp::Pow, base, exponent))
    }

    fn atom(&mut self) -> Result<Id> {
        let t = self.peek().clone();
        match t.tok {
            Tok::Num(v) => {
                self.bump();
                Ok(self.b.num(v))
            }
            Tok::LParen => {
                self.bump();
                self.paren += 1;
                let inner = self.expr()?;
                if *self.peek_tok() != Tok::RParen {
                    let found = self.peek_tok().describe();
                    return Err(self
                        .error_here(format!(
                            "expected ')' to close '(' opened at line {}, column {}, found {found}",
                            t.line, t.column
                        ))
                        .with_related(t.line, t.column));
                }
                self.paren -= 1;
                self.bump();
                Ok(inner)
            }
            Tok::Ident(ref name) => {
                self.bump();
                if *self.peek_tok() == Tok::LParen {
                    self.call(name, &t)
                } else {
                    self.name(name, &t)
                }
            }
            ref other => {
                let found = other.describe();
                Err(self.error_here(format!("expected a number, a name or '(', found {found}")))
            }
        }
    }

    fn name(&mut self, name: &str, at: &Token) -> Result<Id> {
        let err = |m: String| Err(FormulaError::new(at.line, at.column, m));
        if let Some(axis) = VARIABLES.iter().position(|v| *v == name) {
            return Ok(self.b.var(axis as u8));
        }
        if let Some((_, v)) = CONSTANTS.iter().find(|(n, _)| *n == name) {
            return Ok(self.b.num(*v));
        }
        match self.names.get(name) {
            Some(Binding::Definition { id, .. } | Binding::Parameter(id)) => return Ok(*id),
            None => {}
        }
        if function(name).is_some() {
            return err(format!("'{name}' is a function: call it as {name}(...)"));
        }
        if self.defining.as_deref() == Some(name) {
            return err(format!("'{name}' is used in its own definition"));
        }
        err(format!("unknown name '{name}'{}", self.suggest(name)))
    }

    fn call(&mut self, name: &str, at: &Token) -> Result<Id> {
        let Some(func) = function(name) else {
            let msg = if self.names.contains_key(name) || is_reserved(name) {
                format!("'{name}' is not a function")
            } else {
                format!("unknown function '{name}'{}", self.suggest(name))
            };
            return Err(FormulaError::new(at.line, at.column, msg));
        };
        let open = self.bump(); // '('
        self.paren += 1;
        let mut args = Vec::new();
        if *self.peek_tok() == Tok::RParen {
            self.bump();
        } else {
            loop {
                args.push(self.expr()?);
                match self.peek_tok() {
                    Tok::Comma => {
                        self.bump();
                    }
                    Tok::RParen => {
                        self.bump();
                        break;
                    }
                    other => {
                        let found = other.describe();
                        return Err(self
                            .error_here(format!(
                                "expected ',' or ')' to close '(' opened at line {}, column {}, found {found}",
                                open.line, open.column
                            ))
                            .with_related(open.line, open.column));
                    }
                }
            }
        }
        self.paren -= 1;
        let (least, most) = func.arity();
        let got = args.len();
        if got < least || most.is_some_and(|m| got > m) {
            let takes = match most {
                Some(m) if m == least => format!("{least}"),
                _ => format!("at least {least}"),
            };
            let noun = if least == 1 && most == Some(1) { "argument" } else { "arguments" };
            let msg = format!("'{name}' takes {takes} {noun}, got {got}");
            return Err(FormulaError::new(at.line, at.column, msg));
        }
        Ok(self.apply(func, &args))
    }

    /// Builds a call whose argument count has been checked.
    fn apply(&mut self, func: Func, args: &[Id]) -> Id {
        let b = &mut self.b;
        match func {
            Func::Un(op) => b.un(op, args[0]),
            Func::Bin(op) => b.bin(op, args[0], args[1]),
            Func::Fold(op) => args[1..].iter().fold(args[0], |acc, &a| b.bin(op, acc, a)),
            // min(max(v, lo), hi)
            Func::Clamp => {
                let lo = b.bin(BinOp::Max, args[0], args[1]);
                b.bin(BinOp::Min, lo, args[2])
            }
            // a + (b − a)·t
            Func::Mix => {
                let d = b.bin(BinOp::Sub, args[1], args[0]);
                let s = b.bin(BinOp::Mul, d, args[2]);
                b.bin(BinOp::Add, args[0], s)
            }
            // max(a, −b)
            Func::Difference => {
                let nb = b.un(UnOp::Neg, args[1]);
                b.bin(BinOp::Max, args[0], nb)
            }
            Func::SmoothUnion => b.smin(args[0], args[1], args[2]),
            // −smin(−a, −b, k)
            Func::SmoothIntersection => {
                let (na, nb) = (b.un(UnOp::Neg, args[0]), b.un(UnOp::Neg, args[1]));
                let s = b.smin(na, nb, args[2]);
                b.un(UnOp::Neg, s)
            }
            // smooth_intersection(a, −b, k) = −smin(−a, b, k)
            Func::SmoothDifference => {
                let na = b.un(UnOp::Neg, args[0]);
                let s = b.smin(na, args[1], args[2]);
                b.un(UnOp::Neg, s)
            }
        }
    }

    /// `" (did you mean 'r'?)"` for the closest known name, or nothing.
    fn suggest(&self, name: &str) -> String {
        let candidates = self
            .order
            .iter()
            .map(String::as_str)
            .chain(VARIABLES.iter().copied())
            .chain(CONSTANTS.iter().map(|(n, _)| *n))
            .chain(FUNCTIONS.iter().map(|(n, _)| *n));
        let limit = match name.chars().count() {
            0 | 1 => return String::new(),
            2 | 3 => 1,
            _ => 2,
        };
        // Fewest edits first; among equals, one with the same first letter; then the earliest.
        let first = name.chars().next();
        let mut best: Option<((usize, bool), &str)> = None;
        for c in candidates {
            let score = (edit_distance(name, c), c.chars().next() != first);
            if score.0 <= limit && best.is_none_or(|(b, _)| score < b) {
                best = Some((score, c));
            }
        }
        best.map(|(_, c)| format!(" (did you mean '{c}'?)")).unwrap_or_default()
    }
}

/// Levenshtein distance in characters.
fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut prev: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut cur = vec![i + 1; b.len() + 1];
        for (j, &cb) in b.iter().enumerate() {
            cur[j + 1] = (prev[j] + usize::from(ca != cb)).min(prev[j + 1] + 1).min(cur[j] + 1);
        }
        prev = cur;
    }
    prev[b.len()]
}

#[cfg(test)]
mod tests {
    use super::edit_distance;

    #[test]
    fn edit_distances() {
        assert_eq!(edit_distance("rr", "r"), 1);
        assert_eq!(edit_distance("sn", "sin"), 1);
        assert_eq!(edit_distance("kitten", "sitting"), 3);
        assert_eq!(edit_distance("", "abc"), 3);
    }
}
