//! Fuzzing the formula language: parse, compile, evaluate at random points, gradients.
//!
//! Generators: random expression trees (every operator and function, definitions, numbers
//! up to the extremes of `f64`, random spacing, comments and line breaks) rendered as text;
//! those texts mutated (bytes flipped, cut, tokens swapped or replaced by extremes); random
//! strings over the language's alphabet and over all of Unicode; and pathological shapes
//! (nesting far past the limit, chains of 100k operators, long names and numbers).
//!
//! Properties: nothing panics, hangs (each case within its time limit) or allocates past
//! the harness's 1 GiB; a well-formed tree always parses; an error has a 1-based line and
//! column inside the text (or just past it) and a message; a formula that parses evaluates
//! at any point (extremes, NaN and infinities included) with `eval_many`, `eval_layer`
//! and `eval_grad_many` bit-identical to `eval`, and `gradient` equal to `eval_grad_many`'s.
//!
//! CI runs a few hundred cases per property in a few seconds. A longer run:
//! `SKELFORM_FUZZ_SECONDS=3600 cargo test --release -p skelform-field --test fuzz_formula -- --nocapture`
//! runs every property for an hour, side by side as the test harness runs them (as many at
//! once as there are cores, or `--test-threads`), with fresh seeds each round
//! (`SKELFORM_FUZZ_CASES=N` sets the cases per round; see `fuzz/harness.rs`).

#[path = "../../../fuzz/harness.rs"]
mod harness;

use std::time::Duration;

use glam::DVec3;
use proptest::prelude::*;
use skelform_field::Field;
use skelform_field::formula::{Formula, FormulaError};

#[global_allocator]
static GUARD: harness::Guard = harness::Guard;

const LIMIT: Duration = Duration::from_secs(10);

/// Numbers as a formula may write them, extremes included.
fn number() -> impl Strategy<Value = String> {
    prop_oneof![
        4 => (0u32..1000).prop_map(|n| n.to_string()),
        2 => (-1e3f64..1e3).prop_map(|v| format!("{}", v.abs())),
        2 => prop::sample::select(vec![
            "0", "0.0", ".5", "3.", "1e308", "1.7976931348623157e308", "1e-308",
            "5e-324", "2.5E+2", "123456789012345678901234567890", "0.000000001",
            "64", "65", "0.5", "1e18", "9007199254740993",
        ])
        .prop_map(str::to_string),
    ]
}

/// An expression tree that is always well formed, rendered as text. `names` are the
/// definitions visible to it.
fn expr(names: Vec<String>) -> BoxedStrategy<String> {
    let mut leaves: Vec<BoxedStrategy<String>> = vec![
        prop::sample::select(vec!["x", "y", "z", "pi", "e"]).prop_map(str::to_string).boxed(),
        number().boxed(),
    ];
    if !names.is_empty() {
        leaves.push(prop::sample::select(names).boxed());
    }
    let leaf = prop::strategy::Union::new(leaves);
    leaf.prop_recursive(6, 64, 4, |inner| {
        let un = prop::sample::select(vec![
            "abs", "sqrt", "exp", "sin", "cos", "tan", "asin", "acos", "atan", "floor", "ln",
            "log", "sign",
        ]);
        let bin = prop::sample::select(vec![
            "atan2",
            "pow",
            "hypot",
            "min",
            "max",
            "union",
            "intersection",
            "difference",
        ]);
        let tern = prop::sample::select(vec![
            "clamp",
            "mix",
            "lerp",
            "smooth_union",
            "smin",
            "smooth_intersection",
            "smax",
            "smooth_difference",
        ]);
        let many = prop::sample::select(vec!["min", "max", "union", "intersection"]);
        let op = prop::sample::select(vec!["+", "-", "*", "/", "^"]);
        prop_oneof![
            (inner.clone(), op, inner.clone()).prop_map(|(a, o, b)| format!("({a}) {o} ({b})")),
            (inner.clone(), prop::sample::select(vec!["+", "-", "*", "/"]), inner.clone())
                .prop_map(|(a, o, b)| format!("{a}{o}{b}")),
            inner.clone().prop_map(|a| format!("-({a})")),
            inner.clone().prop_map(|a| format!("+({a})")),
            (inner.clone(), number()).prop_map(|(a, n)| format!("({a})^-{n}")),
            (un, inner.clone()).prop_map(|(f, a)| format!("{f}({a})")),
            (bin, inner.clone(), inner.clone()).prop_map(|(f, a, b)| format!("{f}({a}, {b})")),
            (tern, inner.clone(), inner.clone(), inner.clone())
                .prop_map(|(f, a, b, c)| format!("{f}({a},\n {b}, {c})")),
            (many, prop::collection::vec(inner.clone(), 2..6))
                .prop_map(|(f, v)| format!("{f}({})", v.join(", "))),
            inner.prop_map(|a| format!("(\n{a}\n)")),
        ]
    })
    .boxed()
}

/// A whole formula: definitions, each using the ones before it, then the expression.
fn formula() -> impl Strategy<Value = String> {
    (0usize..4, any::<bool>()).prop_flat_map(|(n, comments)| {
        let names: Vec<String> = (0..n).map(|k| format!("d{k}_q")).collect();
        let defs: Vec<BoxedStrategy<String>> = (0..n).map(|k| expr(names[..k].to_vec())).collect();
        (defs, expr(names.clone())).prop_map(move |(defs, last)| {
            let mut text = String::new();
            for (k, d) in defs.iter().enumerate() {
                text += &format!("{} = {d}", names[k]);
                text += if comments { "  # a definition\n" } else { "; " };
            }
            text + &last
        })
    })
}

/// A mutation of a text, at positions given as fractions of its length.
#[derive(Clone, Debug)]
enum Mutation {
    Flip(f64, u8),
    Cut(f64),
    Delete(f64, usize),
    Insert(f64, String),
    SwapTokens(f64, f64),
    Extreme(f64, &'static str),
}

const EXTREMES: &[&str] = &[
    "1e308",
    "-1e308",
    "1e309",
    "-0",
    "NaN",
    "nan",
    "inf",
    "-inf",
    "1e-324",
    "99999999999999999999999999999999999999",
    "-",
    "^",
    "(",
    ")",
    ",",
    "=",
    "#",
    "\n",
    ";",
    "x",
    "sqrt(",
    "min(",
    "clamp(x,",
    "e",
    "pi",
    "1e",
    "1.2.3",
    "..",
    "\u{feff}",
    "é",
    "\r",
];

fn mutation() -> impl Strategy<Value = Mutation> {
    let at = 0.0..1.0f64;
    prop_oneof![
        (at.clone(), any::<u8>()).prop_map(|(a, b)| Mutation::Flip(a, b)),
        at.clone().prop_map(Mutation::Cut),
        (at.clone(), 1usize..8).prop_map(|(a, n)| Mutation::Delete(a, n)),
        (at.clone(), "[ -~\n]{1,6}").prop_map(|(a, s)| Mutation::Insert(a, s)),
        (at.clone(), at.clone()).prop_map(|(a, b)| Mutation::SwapTokens(a, b)),
        (at, prop::sample::select(EXTREMES)).prop_map(|(a, s)| Mutation::Extreme(a, s)),
    ]
}

/// Applies mutations to `text` (bytes, then read back as UTF-8 with replacement).
fn mutate(text: &str, mutations: &[Mutation]) -> String {
    let mut text = text.to_string();
    for m in mutations {
        let pos = |f: f64, len: usize| ((f * len as f64) as usize).min(len);
        match m {
            Mutation::Flip(f, b) => {
                let mut bytes = text.into_bytes();
                if !bytes.is_empty() {
                    let i = pos(*f, bytes.len() - 1);
                    bytes[i] ^= b | 1;
                }
                text = String::from_utf8_lossy(&bytes).into_owned();
            }
            Mutation::Cut(f) => {
                let i = text.floor_char_boundary(pos(*f, text.len()));
                text.truncate(i);
            }
            Mutation::Delete(f, n) => {
                let i = text.floor_char_boundary(pos(*f, text.len()));
                let j = text.floor_char_boundary((i + n).min(text.len()));
                text.replace_range(i..j, "");
            }
            Mutation::Insert(f, s) => {
                let i = text.floor_char_boundary(pos(*f, text.len()));
                text.insert_str(i, s);
            }
            Mutation::SwapTokens(a, b) => {
                let t = formula_tokens(&text);
                if t.len() >= 2 {
                    let (i, j) = (pos(*a, t.len() - 1), pos(*b, t.len() - 1));
                    let (i, j) = (i.min(j), i.max(j));
                    if i != j {
                        harness::swap_spans(&mut text, t[i], t[j]);
                    }
                }
            }
            Mutation::Extreme(f, s) => {
                let t = formula_tokens(&text);
                if !t.is_empty() {
                    let (i, j) = t[pos(*f, t.len() - 1)];
                    text.replace_range(i..j, s);
                }
            }
        }
    }
    text
}

/// Pathological shapes: deep nesting, long chains, long names and numbers.
fn pathological() -> impl Strategy<Value = String> {
    let n = 1usize..200_000;
    prop_oneof![
        n.clone().prop_map(|n| format!("{}x{}", "(".repeat(n), ")".repeat(n))),
        n.clone().prop_map(|n| format!("{}x", "-".repeat(n))),
        n.clone().prop_map(|n| format!("{}x", "x^".repeat(n))),
        n.clone().prop_map(|n| format!("{}x{}", "sin(".repeat(n), ")".repeat(n))),
        n.clone().prop_map(|n| format!("{}x", "(".repeat(n))),
        (n.clone(), prop::sample::select(vec!["+", "-", "*", "/", "+-", "*-"]))
            .prop_map(|(n, op)| vec!["x"; n].join(op)),
        n.clone().prop_map(|n| format!("min({})", vec!["x"; n + 2].join(","))),
        n.clone().prop_map(|n| "x".repeat(n)),
        n.clone().prop_map(|n| format!("1{}", "0".repeat(n))),
        n.clone().prop_map(|n| format!("0.{}1", "0".repeat(n))),
        (1usize..5000).prop_map(|n| {
            let mut t = "a0 = x\n".to_string();
            for k in 1..n {
                t += &format!("a{k} = a{} * a{} + y\n", k - 1, k - 1);
            }
            t + &format!("a{}", n - 1)
        }),
        n.prop_map(|n| "\n".repeat(n) + "x"),
    ]
}

/// Points to evaluate at: ordinary ones, and the extremes.
fn points() -> impl Strategy<Value = Vec<DVec3>> {
    let c = prop_oneof![
        6 => -3.0..3.0f64,
        1 => prop::sample::select(vec![
            0.0, -0.0, 1.0, -1.0, f64::MAX, f64::MIN, f64::MIN_POSITIVE, 5e-324, f64::NAN,
            f64::INFINITY, f64::NEG_INFINITY, 1e300, -1e300, 823549.0, 1e16,
        ]),
    ];
    prop::collection::vec(
        (c.clone(), c.clone(), c).prop_map(|(x, y, z)| DVec3::new(x, y, z)),
        1..40,
    )
}

fn same(a: f64, b: f64) -> bool {
    a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan())
}

/// An error points into the text (or just past its end) and says something.
fn check_error(text: &str, e: &FormulaError) -> Result<(), String> {
    let lines: Vec<&str> = text.split('\n').collect();
    if e.line() == 0 || e.line() > lines.len() + 1 || e.column() == 0 {
        return Err(format!(
            "error at line {}, column {} is outside the text: {e}",
            e.line(),
            e.column()
        ));
    }
    if let Some(l) = lines.get(e.line() - 1)
        && e.column() > l.chars().count() + 1
    {
        return Err(format!("error column {} past the end of line {}: {e}", e.column(), e.line()));
    }
    if e.message().trim().is_empty() {
        return Err("an error without a message".into());
    }
    Ok(())
}

/// Everything a parsed formula offers, at `points`; the results must agree.
fn exercise(f: &Formula, points: &[DVec3]) -> Result<(), String> {
    let one: Vec<f64> = points.iter().map(|&p| f.eval(p)).collect();
    let mut many = vec![0.0; points.len()];
    f.eval_many(points, &mut many);
    let mut values = vec![0.0; points.len()];
    let mut grads = vec![DVec3::ZERO; points.len()];
    f.eval_grad_many(points, &mut values, &mut grads);
    for (k, p) in points.iter().enumerate() {
        if !same(one[k], many[k]) || !same(one[k], values[k]) {
            return Err(format!(
                "at {p}: eval {} but eval_many {} and eval_grad_many {}",
                one[k], many[k], values[k]
            ));
        }
        let g = f.gradient(*p);
        if !(0..3).all(|i| same(g[i], grads[k][i])) {
            return Err(format!("at {p}: gradient {g} but eval_grad_many {}", grads[k]));
        }
    }
    // A small layer through the first point: eval_layer and the sampler agree with eval.
    let p = points[0];
    let xs = [p.x, p.x + 0.5, -p.x];
    let ys = [p.y, 0.25];
    let mut layer = vec![0.0; xs.len() * ys.len()];
    f.eval_layer(&xs, &ys, p.z, &mut layer);
    for (j, &y) in ys.iter().enumerate() {
        for (i, &x) in xs.iter().enumerate() {
            let v = f.eval(DVec3::new(x, y, p.z));
            if !same(v, layer[i + xs.len() * j]) {
                return Err(format!(
                    "eval_layer at ({x}, {y}, {}) {} but eval {v}",
                    p.z,
                    layer[i + xs.len() * j]
                ));
            }
        }
    }
    let _ = f.tape().to_string();
    Ok(())
}

fn parse_and_exercise(text: &str, points: &[DVec3]) -> Result<(), String> {
    match Formula::parse(text) {
        Ok(f) => exercise(&f, points),
        Err(e) => check_error(text, &e),
    }
}

#[test]
fn well_formed_trees_parse_and_evaluate_consistently() {
    harness::fuzz("formula trees", 192, LIMIT, (formula(), points()), |(text, points)| {
        let f =
            Formula::parse(&text).map_err(|e| format!("a well-formed formula is refused: {e}"))?;
        exercise(&f, &points)
    });
}

#[test]
fn mutated_formulas_are_errors_or_formulas() {
    let strategy = (formula(), prop::collection::vec(mutation(), 1..5), points());
    harness::fuzz("formula mutations", 256, LIMIT, strategy, |(text, m, points)| {
        parse_and_exercise(&mutate(&text, &m), &points)
    });
}

#[test]
fn random_strings_are_errors_or_formulas() {
    let strategy = (
        prop_oneof![
            "[xyz0-9.eE+*/^(),;=# \n\t_a-z\u{3c0}\u{e9}-]{0,80}",
            any::<String>(),
            prop::collection::vec(any::<u8>(), 0..64)
                .prop_map(|b| String::from_utf8_lossy(&b).into_owned()),
        ],
        points(),
    );
    harness::fuzz("formula strings", 384, LIMIT, strategy, |(text, points)| {
        parse_and_exercise(&text, &points)
    });
}

#[test]
fn pathological_shapes_are_refused_or_evaluated() {
    harness::fuzz("formula shapes", 32, LIMIT, (pathological(), points()), |(text, points)| {
        let short = |s: &str| s.chars().take(60).collect::<String>();
        parse_and_exercise(&text, &points)
            .map_err(|e| format!("{e} (text starts {:?})", short(&text)))
    });
}

#[test]
fn constants_may_be_anything() {
    let strategy = (
        prop::collection::vec(("[a-zA-Z_][a-zA-Z0-9_]{0,6}|[^\n]{0,4}", any::<f64>()), 0..4),
        formula(),
        points(),
    );
    harness::fuzz("formula constants", 128, LIMIT, strategy, |(consts, text, points)| {
        let consts: Vec<(&str, f64)> = consts.iter().map(|(n, v)| (n.as_str(), *v)).collect();
        let names = consts.iter().map(|c| c.0).collect::<Vec<_>>().join(" + ");
        let text = if names.is_empty() { text } else { format!("{text} + {names}") };
        match Formula::parse_with_constants(&text, &consts) {
            Ok(f) => exercise(&f, &points),
            Err(e) => check_error(&text, &e),
        }
    });
}

/// Spans of the tokens of formula text: names and numbers, or single operators.
fn formula_tokens(text: &str) -> Vec<(usize, usize)> {
    harness::tokens(text, |c| c.is_alphanumeric() || c == '_' || c == '.')
}
