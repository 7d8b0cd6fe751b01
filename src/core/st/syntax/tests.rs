//! The lexer and the parser, unit by unit; the round trip of random expressions through the
//! printer and the parser (proptest); a generated 10,000-line file.

use std::path::Path;

use proptest::prelude::*;

use super::lex::{lex, parse_duration, DurationError, Kw, Tok, P};
use super::parse::{op_level, parse_expr};
use super::*;
use crate::st::ast::*;

// ----- helpers -----

/// The tokens of `text`, without the end of file.
fn toks(text: &str) -> Vec<Tok> {
    let lexed = lex(text);
    assert!(lexed.errors.is_empty(), "{text}: {:?}", lexed.errors);
    let mut toks: Vec<Tok> = lexed.tokens.into_iter().map(|t| t.kind).collect();
    assert_eq!(toks.pop(), Some(Tok::Eof));
    toks
}

fn one_tok(text: &str) -> Tok {
    let mut all = toks(text);
    assert_eq!(all.len(), 1, "{text}: {all:?}");
    all.remove(0)
}

/// The lexer's errors as `line:col: message`.
fn lex_errors(text: &str) -> Vec<String> {
    lex(text).errors.iter().map(|(s, m)| format!("{}:{}: {m}", s.line, s.col)).collect()
}

/// Every diagnostic of a file, as `line:col: message`.
fn errors(text: &str) -> Vec<String> {
    let (_, diags) = parse_file(Path::new("t.st"), text);
    diags.iter().map(|d| format!("{}:{}: {}", d.line, d.col, d.message)).collect()
}

fn parse_ok(text: &str) -> Vec<Item> {
    let (file, diags) = parse_file(Path::new("t.st"), text);
    assert!(diags.is_empty(), "{text}\n{diags}");
    file.items
}

/// The body of `PROGRAM p <text> END_PROGRAM`, which must parse.
fn body(text: &str) -> Vec<Stmt> {
    let items = parse_ok(&format!("PROGRAM p\n{text}\nEND_PROGRAM\n"));
    match items.into_iter().next() {
        Some(Item::Pou(pou)) => pou.body,
        other => panic!("{other:?}"),
    }
}

/// The diagnostics of `PROGRAM p <text> END_PROGRAM` (the text starts on line 2).
fn body_errors(text: &str) -> Vec<String> {
    errors(&format!("PROGRAM p\n{text}\nEND_PROGRAM\n"))
}

fn stmt(text: &str) -> StmtKind {
    let mut stmts = body(text);
    assert_eq!(stmts.len(), 1, "{text}");
    stmts.remove(0).kind
}

fn ex(text: &str) -> Expr {
    parse_expr(text).unwrap_or_else(|e| panic!("{text}: {e:?}"))
}

/// An expression as an S-expression, spans left out.
fn sx(e: &Expr) -> String {
    match &e.kind {
        ExprKind::Literal(l) => lit(l),
        ExprKind::Name(n) => n.name.clone(),
        ExprKind::Member(x, m) => format!("(. {} {})", sx(x), m.name),
        ExprKind::Index(x, i) => {
            format!("([] {} {})", sx(x), i.iter().map(sx).collect::<Vec<_>>().join(" "))
        }
        ExprKind::Bit(x, b) => format!("(bit {} {b})", sx(x)),
        ExprKind::Part(x, size, n) => format!("(part {} {}{n})", sx(x), size.letter()),
        ExprKind::Deref(x) => format!("(^ {})", sx(x)),
        ExprKind::Unary(op, x) => format!("({} {})", unary_text(*op), sx(x)),
        ExprKind::Binary(op, l, r) => format!("({} {} {})", binary_text(*op), sx(l), sx(r)),
        ExprKind::Call { callee, args } => {
            let mut s = format!("(call {}", sx(callee));
            for a in args {
                s.push(' ');
                s.push_str(&match a {
                    Arg::Positional(x) => sx(x),
                    Arg::Input { name, value } => format!("{}:={}", name.name, sx(value)),
                    Arg::Output { name, target, negated } => {
                        let not = if *negated { "NOT " } else { "" };
                        format!("{not}{}=>{}", name.name, sx(target))
                    }
                });
            }
            s + ")"
        }
        ExprKind::Assign(t, v) => format!("(:= {} {})", sx(t), sx(v)),
    }
}

fn lit(l: &Literal) -> String {
    match l {
        Literal::Int(n) | Literal::Based(n) => n.to_string(),
        Literal::Real(x) => format!("{x:?}"),
        Literal::Bool(b) => if *b { "TRUE" } else { "FALSE" }.to_string(),
        Literal::Time(ns) => format!("T{ns}"),
        Literal::Calendar(cal, count) => format!("{}{count}", cal.name()),
        Literal::String(s) => format!("{s:?}"),
        Literal::WString(s) => format!("w{s:?}"),
        Literal::Typed { ty, value } => format!("(# {} {})", ty.name, sx(value)),
    }
}

fn unary_text(op: UnaryOp) -> &'static str {
    match op {
        UnaryOp::Neg => "-",
        UnaryOp::Plus => "+",
        UnaryOp::Not => "NOT",
    }
}

fn binary_text(op: BinaryOp) -> &'static str {
    match op {
        BinaryOp::Or => "OR",
        BinaryOp::OrElse => "OR_ELSE",
        BinaryOp::Xor => "XOR",
        BinaryOp::And => "AND",
        BinaryOp::AndThen => "AND_THEN",
        BinaryOp::Eq => "=",
        BinaryOp::Ne => "<>",
        BinaryOp::Lt => "<",
        BinaryOp::Le => "<=",
        BinaryOp::Gt => ">",
        BinaryOp::Ge => ">=",
        BinaryOp::Add => "+",
        BinaryOp::Sub => "-",
        BinaryOp::Mul => "*",
        BinaryOp::Div => "/",
        BinaryOp::Mod => "MOD",
        BinaryOp::Pow => "**",
    }
}

fn sxs(text: &str) -> String {
    sx(&ex(text))
}

fn sp(line: u32, col: u32) -> Span {
    Span { line, col }
}

// ----- the lexer -----

#[test]
fn lexes_every_punctuation() {
    use P::*;
    let text = ":= => : ; , . .. ( ) [ ] + - * ** / < > <= >= = <> & ^";
    let want = [
        Assign, Arrow, Colon, Semi, Comma, Dot, DotDot, LParen, RParen, LBracket, RBracket, Plus,
        Minus, Star, Power, Slash, Lt, Gt, Le, Ge, Eq, Ne, Amp, Caret,
    ];
    assert_eq!(toks(text), want.iter().map(|&p| Tok::P(p)).collect::<Vec<_>>());
    // Without blanks, the longest operator wins.
    assert_eq!(
        toks("a:=b=>c<=d<>e>=f**g..h"),
        vec![
            Tok::Ident,
            Tok::P(Assign),
            Tok::Ident,
            Tok::P(Arrow),
            Tok::Ident,
            Tok::P(Le),
            Tok::Ident,
            Tok::P(Ne),
            Tok::Ident,
            Tok::P(Ge),
            Tok::Ident,
            Tok::P(Power),
            Tok::Ident,
            Tok::P(DotDot),
            Tok::Ident
        ]
    );
}

#[test]
fn lexes_keywords_in_any_case() {
    let words = [
        ("PROGRAM", Kw::Program),
        ("end_program", Kw::EndProgram),
        ("Function", Kw::Function),
        ("END_FUNCTION", Kw::EndFunction),
        ("function_block", Kw::FunctionBlock),
        ("END_FUNCTION_BLOCK", Kw::EndFunctionBlock),
        ("Class", Kw::Class),
        ("END_CLASS", Kw::EndClass),
        ("type", Kw::Type),
        ("END_TYPE", Kw::EndType),
        ("Struct", Kw::Struct),
        ("END_STRUCT", Kw::EndStruct),
        ("var", Kw::Var),
        ("VAR_INPUT", Kw::VarInput),
        ("VAR_OUTPUT", Kw::VarOutput),
        ("VAR_IN_OUT", Kw::VarInOut),
        ("VAR_TEMP", Kw::VarTemp),
        ("VAR_GLOBAL", Kw::VarGlobal),
        ("VAR_EXTERNAL", Kw::VarExternal),
        ("END_VAR", Kw::EndVar),
        ("CONSTANT", Kw::Constant),
        ("RETAIN", Kw::Retain),
        ("NON_RETAIN", Kw::NonRetain),
        ("at", Kw::At),
        ("ARRAY", Kw::Array),
        ("of", Kw::Of),
        ("String", Kw::String),
        ("if", Kw::If),
        ("THEN", Kw::Then),
        ("ElsIf", Kw::Elsif),
        ("ELSE", Kw::Else),
        ("END_IF", Kw::EndIf),
        ("CASE", Kw::Case),
        ("END_CASE", Kw::EndCase),
        ("FOR", Kw::For),
        ("TO", Kw::To),
        ("BY", Kw::By),
        ("DO", Kw::Do),
        ("END_FOR", Kw::EndFor),
        ("WHILE", Kw::While),
        ("END_WHILE", Kw::EndWhile),
        ("REPEAT", Kw::Repeat),
        ("UNTIL", Kw::Until),
        ("END_REPEAT", Kw::EndRepeat),
        ("EXIT", Kw::Exit),
        ("CONTINUE", Kw::Continue),
        ("RETURN", Kw::Return),
        ("not", Kw::Not),
        ("AND", Kw::And),
        ("and_then", Kw::AndThen),
        ("or", Kw::Or),
        ("OR_ELSE", Kw::OrElse),
        ("XOR", Kw::Xor),
        ("mod", Kw::Mod),
        ("TRUE", Kw::True),
        ("false", Kw::False),
    ];
    for (text, kw) in words {
        assert_eq!(one_tok(text), Tok::Kw(kw), "{text}");
    }
    for name in
        ["x", "_x", "a1", "speed_SP", "__prelude", "END_IFX", "IFS", "a_very_long_name_of_thirty"]
    {
        assert_eq!(one_tok(name), Tok::Ident, "{name}");
    }
}

#[test]
fn lexes_integers_in_every_base() {
    for (text, value) in [
        ("0", 0),
        ("42", 42),
        ("1_000", 1000),
        ("16#FF", 255),
        ("16#ff", 255),
        ("16#DEAD_BEEF", 0xDEAD_BEEF),
        ("2#1010_0101", 0b1010_0101),
        ("8#17", 0o17),
        ("340282366920938463463374607431768211455", u128::MAX),
    ] {
        assert_eq!(one_tok(text), Tok::Int(value), "{text}");
    }
}

#[test]
fn lexes_reals() {
    for (text, value) in [
        ("1.5", 1.5),
        ("0.25", 0.25),
        ("1.0E-3", 1.0e-3),
        ("1e6", 1e6),
        ("2.5e+2", 250.0),
        ("1_000.5", 1000.5),
    ] {
        assert_eq!(one_tok(text), Tok::Real(value), "{text}");
    }
    // `1..10` is a range, `x.3` a bit, `1.e` no real.
    assert_eq!(toks("1..10"), vec![Tok::Int(1), Tok::P(P::DotDot), Tok::Int(10)]);
    assert_eq!(toks("x.3"), vec![Tok::Ident, Tok::P(P::Dot), Tok::Int(3)]);
    assert_eq!(lex_errors("x.1e5"), ["1:3: `1e5` is not a number"]);
}

#[test]
fn reports_bad_numbers() {
    assert_eq!(lex_errors("16#FG"), ["1:1: `16#FG` is not a number"]);
    assert_eq!(lex_errors("  12ab"), ["1:3: `12ab` is not a number"]);
    assert_eq!(lex_errors("3#12"), ["1:1: `3#12` is not a number"]);
    assert_eq!(lex_errors("2#102"), ["1:1: `2#102` is not a number"]);
    assert_eq!(lex_errors("16#"), ["1:1: `16#` is not a number"]);
    assert_eq!(lex_errors("1__0"), ["1:1: `1__0` is not a number"]);
    assert_eq!(lex_errors("1_"), ["1:1: `1_` is not a number"]);
    assert_eq!(lex_errors("1.5x"), ["1:1: `1.5x` is not a number"]);
    assert_eq!(lex_errors("1.5_"), ["1:1: `1.5_` is not a number"]);
    assert_eq!(
        lex_errors("340282366920938463463374607431768211456"),
        ["1:1: `340282366920938463463374607431768211456` is out of range"]
    );
    assert_eq!(lex_errors("1e999"), ["1:1: `1e999` is out of range"]);
    // Still one token, so the parser goes on.
    assert_eq!(lex("16#FG").tokens.len(), 2);
}

#[test]
fn lexes_durations_in_nanoseconds() {
    const S: i128 = 1_000_000_000;
    for (text, ns) in [
        ("T#1s500ms", S + S / 2),
        ("T#1.5s", S + S / 2),
        ("TIME#2m", 120 * S),
        ("t#-5s", -5 * S),
        ("LTIME#1d", 86_400 * S),
        ("LT#1h", 3600 * S),
        ("time#+3s", 3 * S),
        ("T#1d2h3m4s5ms6us7ns", ((86_400 + 7200 + 180 + 4) * S) + 5_006_007),
        ("T#1h_30m", 5400 * S),
        ("T#1_000ms", S),
        ("T#0.5ms", 500_000),
        ("T#1MS", 1_000_000),
        ("T#2US", 2000),
        ("T#3NS", 3),
        ("T#1.25m", 75 * S),
    ] {
        assert_eq!(one_tok(text), Tok::Time(ns), "{text}");
    }
    assert_eq!(toks("T#1s;"), vec![Tok::Time(S), Tok::P(P::Semi)]);
}

#[test]
fn lexes_calendar_literals_as_their_counts() {
    use crate::value::Calendar::*;
    // 2024-03-01 is day 19783 after 1970-01-01.
    const DAY: u64 = 19_783 * 86_400;
    for (text, tok) in [
        ("D#2024-03-01", Tok::Calendar(Date, DAY)),
        ("date#2024-03-01", Tok::Calendar(Date, DAY)),
        ("LDATE#1970-01-02", Tok::Calendar(LDate, 86_400_000_000_000)),
        ("LD#1970-01-02", Tok::Calendar(LDate, 86_400_000_000_000)),
        ("TOD#12:30:15.5", Tok::Calendar(Tod, 45_015_500)),
        ("TIME_OF_DAY#00:00:01", Tok::Calendar(Tod, 1000)),
        ("TOD#12:30", Tok::Calendar(Tod, 45_000_000)),
        ("DT#2024-03-01-00:01", Tok::Calendar(Dt, DAY + 60)),
        ("LTOD#00:00:00.000000001", Tok::Calendar(LTod, 1)),
        ("LTIME_OF_DAY#00:00:01", Tok::Calendar(LTod, 1_000_000_000)),
        ("DT#2024-03-01-12:30:15", Tok::Calendar(Dt, DAY + 45_015)),
        ("DATE_AND_TIME#2024-03-01-00:00:00", Tok::Calendar(Dt, DAY)),
        ("LDT#1970-01-01-00:00:01", Tok::Calendar(LDt, 1_000_000_000)),
        ("LDATE_AND_TIME#1970-01-01-00:00:01", Tok::Calendar(LDt, 1_000_000_000)),
    ] {
        assert_eq!(one_tok(text), tok, "{text}");
    }
    // A minus not followed by a digit, or beyond the form's last field, is the operator.
    assert_eq!(
        toks("D#2024-03-01-d"),
        vec![Tok::Calendar(Date, DAY), Tok::P(P::Minus), Tok::Ident]
    );
    assert_eq!(
        toks("TOD#01:00:00-t"),
        vec![Tok::Calendar(Tod, 3_600_000), Tok::P(P::Minus), Tok::Ident]
    );
    assert_eq!(
        lex_errors("x := D#2024-13-01;"),
        ["1:6: `D#2024-13-01` is not a valid DATE: month 13 is not 1 to 12"]
    );
}

#[test]
fn reports_bad_durations() {
    assert_eq!(lex_errors("T#5x"), ["1:1: `T#5x` is not a duration: unknown unit `x`"]);
    assert_eq!(lex_errors("T#5"), ["1:1: `T#5` is not a duration: missing unit after `5`"]);
    assert_eq!(lex_errors("T#1s5"), ["1:1: `T#1s5` is not a duration: missing unit after `5`"]);
    assert_eq!(lex_errors("T#s"), ["1:1: `T#s` is not a duration: expected a number, found `s`"]);
    assert_eq!(
        lex_errors("x := T#;"),
        ["1:6: `T#` is not a duration: expected a number, found nothing"]
    );
    // u64 nanoseconds hold about 213,503 days: beyond i64's 106,751 the compiler judges (CODESYS's
    // unsigned LTIME, a habit); beyond u64 the lexer refuses.
    assert_eq!(lex_errors("T#106752d"), Vec::<String>::new());
    assert_eq!(lex_errors("LTIME#213503D23H34M33S709MS551US615NS"), Vec::<String>::new());
    assert_eq!(
        lex_errors("LTIME#213503D23H34M33S709MS551US616NS"),
        ["1:1: `LTIME#213503D23H34M33S709MS551US616NS` is out of range"]
    );
    assert_eq!(lex_errors("T#213504d"), ["1:1: `T#213504d` is out of range"]);
    assert_eq!(lex_errors("T#-106752d"), ["1:1: `T#-106752d` is out of range"]);
    assert_eq!(
        lex_errors("T#99999999999999999999999999999999999999999d"),
        ["1:1: `T#99999999999999999999999999999999999999999d` is out of range"]
    );
    assert_eq!(parse_duration("-9223372036854775808ns"), Ok(i128::from(i64::MIN)));
    assert_eq!(parse_duration("-9223372036854775809ns"), Err(DurationError::Range));
    assert_eq!(parse_duration("18446744073709551615ns"), Ok(i128::from(u64::MAX)));
    assert_eq!(parse_duration("18446744073709551616ns"), Err(DurationError::Range));
    assert_eq!(parse_duration("1s_2ms_"), Ok(1_002_000_000));
}

#[test]
fn lexes_strings_and_escapes() {
    assert_eq!(one_tok("'text'"), Tok::Str("text".into()));
    assert_eq!(one_tok("''"), Tok::Str(String::new()));
    assert_eq!(
        one_tok("'$$ $' $L $N $P $R $T $l $n $p $r $t'"),
        Tok::Str("$ ' \n \n \x0c \r \t \n \n \x0c \r \t".into())
    );
    assert_eq!(one_tok("'$41$62$0a'"), Tok::Str("Ab\n".into()));
    assert_eq!(one_tok("'$FF'"), Tok::Str("\u{ff}".into()));
    assert_eq!(one_tok("'héllo'"), Tok::Str("héllo".into()));
    assert_eq!(lex_errors("'a$qb'"), ["1:3: invalid escape `$q` in a string"]);
    assert_eq!(lex_errors("'a$4'"), ["1:3: invalid escape `$4` in a string"]);
    assert_eq!(lex_errors("x := 'abc\ny"), ["1:6: unterminated string"]);
    assert_eq!(lex_errors("'abc"), ["1:1: unterminated string"]);
    assert_eq!(one_tok("\"wide\""), Tok::WStr("wide".into()));
    assert_eq!(one_tok("\"$\"$$ä$20AC$0041$L\""), Tok::WStr("\"$ä€A\n".into()));
    assert_eq!(one_tok("\"it's\""), Tok::WStr("it's".into()));
    assert_eq!(lex_errors("\"$D800\""), ["1:2: invalid escape `$D800` in a string"]);
    assert_eq!(lex("\"wide\" x").tokens.len(), 3);
}

#[test]
fn lexes_typed_literal_prefixes_and_locations() {
    assert_eq!(toks("INT#5"), vec![Tok::TypedPrefix, Tok::Int(5)]);
    assert_eq!(toks("int#16#FF"), vec![Tok::TypedPrefix, Tok::Int(255)]);
    assert_eq!(toks("Color#Red"), vec![Tok::TypedPrefix, Tok::Ident]);
    assert_eq!(toks("BOOL#TRUE"), vec![Tok::TypedPrefix, Tok::Kw(Kw::True)]);
    assert_eq!(toks("STRING#'a'"), vec![Tok::TypedPrefix, Tok::Str("a".into())]);
    for text in ["%D00100", "%P0040", "%M0000", "%D00010.3", "%IX0.0", "%QX0.1", "%MW10", "%ID4"] {
        assert_eq!(one_tok(text), Tok::Location, "{text}");
    }
    assert_eq!(lex_errors("x AT % : INT"), ["1:6: expected an address after `%`"]);
}

#[test]
fn skips_comments_and_pragmas() {
    assert_eq!(toks("a (* one *) b"), vec![Tok::Ident, Tok::Ident]);
    assert_eq!(toks("a (* (* nested *) still *) b"), vec![Tok::Ident, Tok::Ident]);
    assert_eq!(toks("a /* /* nested */ still */ b"), vec![Tok::Ident, Tok::Ident]);
    assert_eq!(toks("a /* (* */ b"), vec![Tok::Ident, Tok::Ident]);
    assert_eq!(toks("a // to the end\nb"), vec![Tok::Ident, Tok::Ident]);
    assert_eq!(toks("a {attribute 'hide'} b"), vec![Tok::Ident, Tok::Ident]);
    assert_eq!(toks("a (**) b (***) c"), vec![Tok::Ident, Tok::Ident, Tok::Ident]);
    assert_eq!(
        lex_errors("a\n  (* open (* x *)\nb"),
        ["3:2: unterminated comment (opened at line 2)"]
    );
    assert_eq!(lex_errors("/* x"), ["1:5: unterminated comment (opened at line 1)"]);
    assert_eq!(lex_errors("x {pragma"), ["1:10: unterminated pragma (opened at line 1)"]);
    assert!(lex("(* x").eof_in_comment);
}

#[test]
fn skips_a_multiprog_description_as_a_comment() {
    // KW-Software MULTIPROG's (PC WORX's) ST export: a POU's description is free text between
    // two comments; IronPLC's oscat.st test file has one.
    let text =
        "(*@KEY@:DESCRIPTION*)\nversion 1.0\tgarret's é\n(* x *)\n(*@KEY@:END_DESCRIPTION*) a\nb";
    let lexed = lex(text);
    assert!(lexed.errors.is_empty(), "{:?}", lexed.errors);
    let spans: Vec<(u32, u32)> = lexed.tokens.iter().map(|t| (t.span.line, t.span.col)).collect();
    assert_eq!(spans, [(4, 27), (5, 1), (5, 2)], "a, b and the end, on the lines they are");
    // any case, as the other keywords
    assert_eq!(toks("(*@key@:description*) x + 1 (*@Key@:End_Description*) a"), vec![Tok::Ident]);
    // another comment is just a comment
    assert_eq!(toks("(*@KEY@:OTHER*) a"), vec![Tok::Ident]);
    assert_eq!(
        lex_errors("a\n(*@KEY@:DESCRIPTION*) text"),
        ["2:27: no `(*@KEY@:END_DESCRIPTION*)` closes the description `(*@KEY@:DESCRIPTION*)` opened at line 2"]
    );
}

#[test]
fn reports_unexpected_characters() {
    assert_eq!(lex_errors("a @ b"), ["1:3: unexpected character `@`"]);
    assert_eq!(lex_errors("a\n ü"), ["2:2: unexpected character `ü`"]);
    assert_eq!(toks("a (* @ *) b"), vec![Tok::Ident, Tok::Ident]);
}

#[test]
fn counts_lines_and_columns_in_characters() {
    let lexed = lex("a := 'héé' + b;\n\tc\r\n  (* é\n *) d");
    let spans: Vec<(u32, u32)> = lexed.tokens.iter().map(|t| (t.span.line, t.span.col)).collect();
    assert_eq!(spans, [(1, 1), (1, 3), (1, 6), (1, 12), (1, 14), (1, 15), (2, 2), (4, 5), (4, 6)]);
}

// ----- expressions -----

#[test]
fn precedence_follows_the_table() {
    assert_eq!(
        sxs("a OR b XOR c AND d = e < f + g * h ** i"),
        "(OR a (XOR b (AND c (= d (< e (+ f (* g (** h i))))))))"
    );
    assert_eq!(
        sxs("i ** h * g + f < e = d AND c XOR b OR a"),
        "(OR (XOR (AND (= (< (+ (* (** i h) g) f) e) d) c) b) a)"
    );
    // Every pair of adjacent levels, both ways round.
    let levels: [&[&str]; 7] = [
        &["OR", "OR_ELSE"],
        &["XOR"],
        &["AND", "&", "AND_THEN"],
        &["=", "<>"],
        &["<", ">", "<=", ">="],
        &["+", "-"],
        &["*", "/", "MOD"],
    ];
    for (i, low) in levels.iter().enumerate() {
        for high in levels.iter().skip(i + 1).copied().chain([&["**"][..]]) {
            for lo in *low {
                for hi in high {
                    let name =
                        |op: &str| if op == "&" { "AND".to_string() } else { op.to_string() };
                    let (l, h) = (name(lo), name(hi));
                    assert_eq!(sxs(&format!("a {lo} b {hi} c")), format!("({l} a ({h} b c))"));
                    assert_eq!(sxs(&format!("a {hi} b {lo} c")), format!("({l} ({h} a b) c)"));
                }
            }
        }
    }
}

#[test]
fn binary_operators_are_left_associative() {
    for op in [
        "OR", "OR_ELSE", "XOR", "AND", "AND_THEN", "=", "<>", "<", ">", "<=", ">=", "+", "-", "*",
        "/", "MOD", "**",
    ] {
        assert_eq!(sxs(&format!("a {op} b {op} c")), format!("({op} ({op} a b) c)"));
    }
    assert_eq!(sxs("a & b"), "(AND a b)");
    // CODESYS ranks AND_THEN with AND and OR_ELSE with OR: left to right among them
    assert_eq!(sxs("a AND b AND_THEN c AND d"), "(AND (AND_THEN (AND a b) c) d)");
    assert_eq!(sxs("a OR_ELSE b OR c"), "(OR (OR_ELSE a b) c)");
    assert_eq!(sxs("a - b + c - d"), "(- (+ (- a b) c) d)");
    assert_eq!(sxs("2 ** 3 ** 2"), "(** (** 2 3) 2)");
}

#[test]
fn unary_operators_sit_below_power() {
    assert_eq!(sxs("-2 ** 2"), "(- (** 2 2))");
    assert_eq!(sxs("NOT a ** b"), "(NOT (** a b))");
    assert_eq!(sxs("-a * b"), "(* (- a) b)");
    assert_eq!(sxs("a * -b"), "(* a (- b))");
    assert_eq!(sxs("NOT a AND b"), "(AND (NOT a) b)");
    assert_eq!(sxs("NOT a = b"), "(= (NOT a) b)");
    assert_eq!(sxs("- -a"), "(- (- a))");
    assert_eq!(sxs("+a"), "(+ a)");
    assert_eq!(sxs("NOT NOT a"), "(NOT (NOT a))");
    assert_eq!(sxs("2 ** -1"), "(** 2 (- 1))");
    assert_eq!(sxs("-(a + b)"), "(- (+ a b))");
    assert_eq!(sxs("(a OR b) AND c"), "(AND (OR a b) c)");
}

#[test]
fn parses_postfix_operators() {
    assert_eq!(sxs("a.b.c"), "(. (. a b) c)");
    assert_eq!(sxs("a[1, j + 1]"), "([] a 1 (+ j 1))");
    assert_eq!(sxs("a[i].x.3"), "(bit (. ([] a i) x) 3)");
    assert_eq!(sxs("w.15"), "(bit w 15)");
    assert_eq!(sxs("f()"), "(call f)");
    assert_eq!(sxs("f(1, 2)"), "(call f 1 2)");
    assert_eq!(
        sxs("inst.fb(IN := x, Q => y, NOT QN => z)"),
        "(call (. inst fb) IN:=x Q=>y NOT QN=>z)"
    );
    assert_eq!(sxs("f(NOT a, NOT b OR c)"), "(call f (NOT a) (OR (NOT b) c))");
    assert_eq!(sxs("f(x)[2]"), "([] (call f x) 2)");
    assert_eq!(sxs("-a.b ** 2"), "(- (** (. a b) 2))");
    assert_eq!(sxs("(a).b"), "(. a b)");
}

#[test]
fn parses_references() {
    assert_eq!(sxs("p^"), "(^ p)");
    assert_eq!(sxs("p^.x"), "(. (^ p) x)");
    assert_eq!(sxs("p^[i + 1]"), "([] (^ p) (+ i 1))");
    assert_eq!(sxs("(p + 2)^"), "(^ (+ p 2))");
    assert_eq!(sxs("a.next^.v^"), "(^ (. (^ (. a next)) v))");
    assert_eq!(sxs("-p^ * 2"), "(* (- (^ p)) 2)");
    assert_eq!(sxs("ADR(buf) + 4"), "(+ (call ADR buf) 4)");
    let ty = |text: &str| decl(&format!("x : {text};")).ty;
    let TypeRef::Ref { kind: RefKind::RefTo, to, span } = ty("REF_TO INT") else { panic!() };
    assert!(matches!(*to, TypeRef::Named(ref n) if n.is("INT")));
    assert_eq!(span, sp(3, 5));
    let TypeRef::Ref { kind: RefKind::Pointer, to, .. } = ty("pointer To ARRAY [1..32767] OF BYTE")
    else {
        panic!()
    };
    assert!(matches!(*to, TypeRef::Array { .. }));
    let TypeRef::Ref { kind: RefKind::Reference, to, .. } = ty("REFERENCE TO REF_TO Axis") else {
        panic!()
    };
    assert!(matches!(*to, TypeRef::Ref { kind: RefKind::RefTo, .. }));
    // Without TO, POINTER is a type's name like any other.
    assert!(matches!(ty("Pointer"), TypeRef::Named(ref n) if n.is("pointer")));
    let StmtKind::RefAssign { target, value } = stmt("r REF= a[2];") else { panic!() };
    assert_eq!((sx(&target), sx(&value)), ("r".to_string(), "([] a 2)".to_string()));
    assert!(matches!(stmt("p^ := p^ + 1;"), StmtKind::Assign { .. }));
}

#[test]
fn parses_literals() {
    assert_eq!(sxs("42"), "42");
    assert_eq!(sxs("16#FF"), "255");
    assert_eq!(sxs("1.5"), "1.5");
    assert_eq!(sxs("TRUE"), "TRUE");
    assert_eq!(sxs("false"), "FALSE");
    assert_eq!(sxs("T#1ms"), "T1000000");
    assert_eq!(sxs("'a$'b'"), "\"a'b\"");
    assert_eq!(sxs("INT#5"), "(# INT 5)");
    assert_eq!(sxs("INT#16#FF"), "(# INT 255)");
    assert_eq!(sxs("INT#-5"), "(# INT (- 5))");
    assert_eq!(sxs("REAL#1"), "(# REAL 1)");
    assert_eq!(sxs("BOOL#1"), "(# BOOL 1)");
    assert_eq!(sxs("BOOL#TRUE"), "(# BOOL TRUE)");
    assert_eq!(sxs("Color#Red"), "(# Color Red)");
    assert_eq!(sxs("-INT#5"), "(- (# INT 5))");
}

#[test]
fn expression_spans_are_first_characters() {
    let e = ex("a + (b * c)");
    assert_eq!(e.span, sp(1, 1));
    let ExprKind::Binary(_, l, r) = &e.kind else { panic!() };
    assert_eq!((l.span, r.span), (sp(1, 1), sp(1, 6)));
    let e = ex("(a + b) * c");
    assert_eq!(e.span, sp(1, 1));
    let ExprKind::Binary(_, l, _) = &e.kind else { panic!() };
    assert_eq!(l.span, sp(1, 2));
    let e = ex("  -x.y[1]");
    assert_eq!(e.span, sp(1, 3));
    let ExprKind::Unary(_, x) = &e.kind else { panic!() };
    assert_eq!(x.span, sp(1, 4));
    let e = ex("INT#5");
    let ExprKind::Literal(Literal::Typed { ty, value }) = &e.kind else { panic!() };
    assert_eq!((e.span, ty.span, value.span), (sp(1, 1), sp(1, 1), sp(1, 5)));
    let e = ex("f(IN := x)");
    let ExprKind::Call { args, .. } = &e.kind else { panic!() };
    let Arg::Input { name, value } = &args[0] else { panic!() };
    assert_eq!((name.span, value.span), (sp(1, 3), sp(1, 9)));
}

#[test]
fn reports_bad_expressions() {
    let msg = |text: &str| {
        parse_expr(text)
            .unwrap_err()
            .iter()
            .map(|(s, m)| format!("{}:{}: {m}", s.line, s.col))
            .collect::<Vec<_>>()
    };
    assert_eq!(msg("a +"), ["1:4: expected an expression, found end of file"]);
    assert_eq!(msg("(a"), ["1:3: expected `)`, found end of file"]);
    assert_eq!(msg("a[1"), ["1:4: expected `,` or `]`, found end of file"]);
    assert_eq!(msg("f(1 2)"), ["1:5: expected `,` or `)`, found `2`"]);
    assert_eq!(msg("a.+"), ["1:3: expected a member name or a bit number after `.`, found `+`"]);
    assert_eq!(msg("a.300"), ["1:3: bit number `300` is too large"]);
    assert_eq!(msg("INT#*"), ["1:5: expected a literal after the type prefix, found `*`"]);
    let deep = format!("{}a{}", "(".repeat(100), ")".repeat(100));
    assert_eq!(msg(&deep), [format!("1:{}: nested more than 64 levels deep", 65)]);
    let deep = format!("{}a", "-".repeat(200));
    assert_eq!(msg(&deep).len(), 1);
}

// ----- statements -----

#[test]
fn parses_assignments_and_calls() {
    let StmtKind::Assign { target, value } = stmt("a[i].b := x + 1;") else { panic!() };
    assert_eq!((sx(&target), sx(&value)), ("(. ([] a i) b)".into(), "(+ x 1)".into()));
    let StmtKind::Call(call) = stmt("fb(IN := x, Q => y);") else { panic!() };
    assert_eq!(sx(&call), "(call fb IN:=x Q=>y)");
    let StmtKind::Call(call) = stmt("f(1, 2);") else { panic!() };
    assert_eq!(sx(&call), "(call f 1 2)");
    let StmtKind::Call(call) = stmt("a.b.c();") else { panic!() };
    assert_eq!(sx(&call), "(call (. (. a b) c))");
    assert!(matches!(stmt(";"), StmtKind::Empty));
    assert!(matches!(stmt("EXIT;"), StmtKind::Exit));
    assert!(matches!(stmt("continue;"), StmtKind::Continue));
    assert!(matches!(stmt("RETURN;"), StmtKind::Return));
}

#[test]
fn parses_if() {
    let StmtKind::If { branches, otherwise } =
        stmt("IF a THEN x := 1; ELSIF b THEN x := 2; y := 3; ELSIF c THEN ; ELSE x := 4; END_IF;")
    else {
        panic!()
    };
    let shape: Vec<(String, usize)> = branches.iter().map(|(c, b)| (sx(c), b.len())).collect();
    assert_eq!(shape, [("a".into(), 1), ("b".into(), 2), ("c".into(), 1)]);
    let (span, stmts) = otherwise.unwrap();
    assert_eq!((span, stmts.len()), (sp(2, 63), 1));
    let StmtKind::If { branches, otherwise } = stmt("IF a THEN END_IF;") else { panic!() };
    assert_eq!((branches.len(), branches[0].1.len(), otherwise), (1, 0, None));
}

#[test]
fn parses_case() {
    let text = "CASE s OF\n 1, 3..5: x := 1;\n Red, -2: x := 2; y := 1;\n Color#Blue: ;\n Color.Green: x := 3;\nELSE x := 0; y := 0;\nEND_CASE;";
    let StmtKind::Case { selector, arms, otherwise } = stmt(text) else { panic!() };
    assert_eq!(sx(&selector), "s");
    let labels: Vec<Vec<String>> = arms
        .iter()
        .map(|arm| {
            arm.labels
                .iter()
                .map(|l| match l {
                    CaseLabel::Value(v) => sx(v),
                    CaseLabel::Range(a, b) => format!("{}..{}", sx(a), sx(b)),
                })
                .collect()
        })
        .collect();
    assert_eq!(
        labels,
        [vec!["1", "3..5"], vec!["Red", "(- 2)"], vec!["(# Color Blue)"], vec!["(. Color Green)"]]
    );
    let bodies: Vec<usize> = arms.iter().map(|a| a.body.len()).collect();
    assert_eq!(bodies, [1, 2, 1, 1]);
    assert_eq!(arms[1].span, sp(4, 2));
    let (span, stmts) = otherwise.unwrap();
    assert_eq!((span, stmts.len()), (sp(7, 1), 2));
    let StmtKind::Case { arms, otherwise, .. } = stmt("CASE s OF END_CASE;") else { panic!() };
    assert!(arms.is_empty() && otherwise.is_none());
    // A nested IF's ELSE is the IF's.
    let StmtKind::Case { arms, otherwise, .. } =
        stmt("CASE s OF 1: IF a THEN x := 1; ELSE x := 2; END_IF; 2: x := 3; END_CASE;")
    else {
        panic!()
    };
    assert_eq!((arms.len(), otherwise.is_none()), (2, true));
}

#[test]
fn parses_assignment_expressions() {
    // chained, right-associative, and noted as a habit at each inner `:=`
    let StmtKind::Assign { target, value } = stmt("a := b := c := FALSE;") else { panic!() };
    assert_eq!((sx(&target), sx(&value)), ("a".into(), "(:= b (:= c FALSE))".into()));
    let StmtKind::If { branches, .. } = stmt("IF (i := i + 1) >= 3 THEN i := 0; END_IF;") else {
        panic!()
    };
    assert_eq!(sx(&branches[0].0), "(>= (:= i (+ i 1)) 3)");
    // a call's `name :=` stays a named argument; doubled parentheses give an assignment
    let StmtKind::Call(call) = stmt("f(x := 1, (y := 2));") else { panic!() };
    assert_eq!(sx(&call), "(call f x:=1 (:= y 2))");
    // a whole condition may be one (CODESYS's example); inside an operation it needs
    // parentheses
    let StmtKind::If { branches, .. } = stmt("IF b := (i = 1) THEN i := i + 1; END_IF;") else {
        panic!()
    };
    assert_eq!(sx(&branches[0].0), "(:= b (= i 1))");
    let StmtKind::While { cond, .. } = stmt("WHILE go := n < 5 DO n := n + 1; END_WHILE;") else {
        panic!()
    };
    assert_eq!(sx(&cond), "(:= go (< n 5))");
    assert_eq!(body_errors("f(1, x + y := 2);"), ["2:12: expected `,` or `)`, found `:=`"]);
}

#[test]
fn parses_loops() {
    let StmtKind::For { var, from, to, by, body } =
        stmt("FOR i := 1 TO n - 1 BY -2 DO x := i; END_FOR;")
    else {
        panic!()
    };
    assert_eq!((sx(&var), sx(&from), sx(&to)), ("i".into(), "1".into(), "(- n 1)".into()));
    assert_eq!((by.map(|b| sx(&b)), body.len()), (Some("(- 2)".into()), 1));
    let StmtKind::For { by, .. } = stmt("FOR i := 0 TO 9 DO END_FOR;") else { panic!() };
    assert!(by.is_none());
    // TwinCAT counts in an element or a member too (a habit, noted for `[st] strict`)
    let StmtKind::For { var, .. } = stmt("FOR a[1] := 0 TO 9 DO END_FOR;") else { panic!() };
    assert_eq!(sx(&var), "([] a 1)");
    let StmtKind::For { var, .. } = stmt("FOR s.n := 0 TO 9 DO END_FOR;") else { panic!() };
    assert_eq!(sx(&var), "(. s n)");
    let StmtKind::While { cond, body } = stmt("WHILE a < 10 DO a := a + 1; EXIT; END_WHILE;")
    else {
        panic!()
    };
    assert_eq!((sx(&cond), body.len()), ("(< a 10)".into(), 2));
    let StmtKind::Repeat { body, until } =
        stmt("REPEAT a := a + 1; CONTINUE; UNTIL a > 10 END_REPEAT;")
    else {
        panic!()
    };
    assert_eq!((sx(&until), body.len()), ("(> a 10)".into(), 2));
}

#[test]
fn statement_spans_are_first_tokens() {
    let stmts = body("  x := 1;\nIF a THEN\n    y := 2;\nEND_IF;\n;");
    let spans: Vec<Span> = stmts.iter().map(|s| s.span).collect();
    assert_eq!(spans, [sp(2, 3), sp(3, 1), sp(6, 1)]);
    let StmtKind::If { branches, .. } = &stmts[1].kind else { panic!() };
    assert_eq!(branches[0].1[0].span, sp(4, 5));
}

// ----- declarations -----

fn pou(text: &str) -> Pou {
    match parse_ok(text).into_iter().next() {
        Some(Item::Pou(pou)) => pou,
        other => panic!("{other:?}"),
    }
}

#[test]
fn parses_methods_properties_and_interfaces() {
    let fb = pou("FUNCTION_BLOCK PUBLIC ABSTRACT D EXTENDS B IMPLEMENTS I, Lib.J\nVAR x : INT; END_VAR\nMETHOD PRIVATE FINAL M : INT\nVAR_INPUT a : INT; END_VAR\nM := a;\nEND_METHOD\nx := M(1);\nPROPERTY P : INT\nGET P := x; END_GET\nSET x := P; END_SET\nEND_PROPERTY\nEND_FUNCTION_BLOCK\nMETHOD After\nEND_METHOD");
    let oop = &fb.oop;
    assert!(oop.is_abstract && !oop.is_final);
    assert!(matches!(&oop.extends, Some(b) if b.is("B")));
    let names: Vec<&str> = oop.implements.iter().map(|i| i.name.as_str()).collect();
    assert_eq!(names, ["I", "Lib.J"]);
    assert_eq!(fb.body.len(), 1, "the body between the method and the property");
    let methods: Vec<(&str, Access, bool)> =
        oop.methods.iter().map(|m| (m.pou.name.name.as_str(), m.access, m.is_final)).collect();
    assert_eq!(methods, [("M", Access::Private, true), ("After", Access::Public, false)]);
    let p = &oop.properties[0];
    let set = p.set.as_ref().unwrap();
    assert_eq!(set.vars[0].kind, VarKind::Input, "SET receives the value in the property's name");
    assert!(set.vars[0].decls[0].names[0].is("P"));
    assert!(p.get.as_ref().unwrap().return_type.is_some());
    let items = parse_ok("INTERFACE I EXTENDS J, K\nMETHOD M : BOOL\nVAR_INPUT a : INT; END_VAR\nEND_METHOD\nPROPERTY P : INT\nGET\nEND_GET\nEND_PROPERTY\nEND_INTERFACE");
    let Some(Item::Interface(itf)) = items.first() else { panic!("{items:?}") };
    assert_eq!((itf.extends.len(), itf.methods.len(), itf.properties.len()), (2, 1, 1));
}

#[test]
fn a_class_is_a_function_block_marked_class() {
    let c = pou("CLASS FINAL Valve EXTENDS Part IMPLEMENTS IOpen\nVAR open : BOOL; END_VAR\nMETHOD Open\nopen := TRUE;\nEND_METHOD\nEND_CLASS");
    assert_eq!((c.kind, c.name.name.as_str(), c.end), (PouKind::FunctionBlock, "Valve", sp(6, 1)));
    assert!(c.oop.is_class && c.oop.is_final);
    assert!(c.oop.extends.as_ref().is_some_and(|b| b.is("Part")));
    assert_eq!((c.oop.implements.len(), c.oop.methods.len(), c.body.len()), (1, 1, 0));
    let fb = pou("FUNCTION_BLOCK Fb END_FUNCTION_BLOCK");
    assert!(!fb.oop.is_class);
}

#[test]
fn parses_pous() {
    let p = pou("PROGRAM Main\nVAR x : INT; END_VAR\nx := 1;\nEND_PROGRAM");
    assert_eq!(
        (p.kind, p.name.name.as_str(), p.span, p.end),
        (PouKind::Program, "Main", sp(1, 1), sp(4, 1))
    );
    assert_eq!((p.vars.len(), p.body.len(), p.return_type), (1, 1, None));
    let f = pou("FUNCTION Add : DINT\nVAR_INPUT a, b : DINT; END_VAR\nAdd := a + b;\nEND_FUNCTION");
    assert_eq!(f.kind, PouKind::Function);
    assert!(matches!(f.return_type, Some(TypeRef::Named(ref n)) if n.is("dint")));
    let f = pou("function f VAR_INPUT a : INT; END_VAR end_function");
    assert_eq!((f.return_type, f.end), (None, sp(1, 39)));
    let fb = pou("FUNCTION_BLOCK Fb\nVAR_INPUT i : BOOL; END_VAR\nVAR_OUTPUT q : BOOL; END_VAR\nVAR_IN_OUT io : INT; END_VAR\nVAR_TEMP t : INT; END_VAR\nVAR_EXTERNAL g : INT; END_VAR\nq := i;\nEND_FUNCTION_BLOCK");
    let kinds: Vec<VarKind> = fb.vars.iter().map(|v| v.kind).collect();
    assert_eq!(
        kinds,
        [VarKind::Input, VarKind::Output, VarKind::InOut, VarKind::Temp, VarKind::External]
    );
    let items = parse_ok("VAR_GLOBAL CONSTANT RETAIN Max : INT := 10; END_VAR\nVAR_GLOBAL NON_RETAIN g : BOOL; END_VAR PROGRAM a END_PROGRAM PROGRAM b END_PROGRAM");
    assert_eq!(items.len(), 4);
    let Item::Globals(g) = &items[0] else { panic!() };
    assert_eq!((g.kind, g.constant, g.retain, g.span), (VarKind::Global, true, true, sp(1, 1)));
    let Item::Globals(g) = &items[1] else { panic!() };
    assert_eq!((g.constant, g.retain), (false, false));
    assert!(parse_ok("").is_empty());
}

#[test]
fn var_block_qualifiers_come_in_any_order() {
    for (q, constant, retain) in [
        ("", false, false),
        ("CONSTANT", true, false),
        ("RETAIN", false, true),
        ("RETAIN CONSTANT", true, true),
        ("CONSTANT RETAIN", true, true),
        ("NON_RETAIN", false, false),
        ("NON_RETAIN CONSTANT", true, false),
    ] {
        let p = pou(&format!("PROGRAM p VAR {q} x : INT; END_VAR END_PROGRAM"));
        assert_eq!((p.vars[0].constant, p.vars[0].retain), (constant, retain), "{q}");
    }
}

#[test]
fn persistent_is_a_retain_qualifier_in_any_order_and_still_a_name() {
    for (q, constant, persistent) in [
        ("PERSISTENT", false, true),
        ("RETAIN PERSISTENT", false, true),
        ("PERSISTENT RETAIN", false, true),
        ("persistent CONSTANT", true, true),
        ("CONSTANT PERSISTENT RETAIN", true, true),
        ("RETAIN", false, false),
    ] {
        let p = pou(&format!("PROGRAM p VAR {q} x : INT; END_VAR END_PROGRAM"));
        let b = &p.vars[0];
        assert_eq!((b.constant, b.retain, b.persistent), (constant, true, persistent), "{q}");
        assert_eq!(b.decls[0].names[0].name, "x", "{q}");
    }
    // a variable called `persistent`, alone or first of several, or located
    for decl in ["persistent : BOOL;", "persistent, b : BOOL;", "persistent AT %MX0.0 : BOOL;"] {
        let p = pou(&format!("PROGRAM p VAR {decl} END_VAR END_PROGRAM"));
        assert!(!p.vars[0].persistent && !p.vars[0].retain, "{decl}");
        assert!(p.vars[0].decls[0].names[0].is("persistent"), "{decl}");
    }
    let text = "VAR_GLOBAL PERSISTENT g : INT; END_VAR\nPROGRAM p END_PROGRAM\n";
    assert_eq!(habits(text), ["1:12: Persistent"]);
}

#[test]
fn a_semicolon_alone_in_a_var_block_is_an_empty_declaration() {
    let text =
        "PROGRAM p\nVAR\n    a : LREAL := 630.0;;\n    ;\n    b : INT;\nEND_VAR\nEND_PROGRAM\n";
    assert_eq!(habits(text), ["3:24: EmptyDeclaration", "4:5: EmptyDeclaration"]);
    let p = pou(text);
    let names: Vec<&str> = p.vars[0].decls.iter().map(|d| d.names[0].name.as_str()).collect();
    assert_eq!(names, ["a", "b"]);
}

#[test]
fn a_comma_after_the_last_argument_ends_the_call() {
    let text = "PROGRAM p\nfb(a := x,\n   b => y, );\nn := F(1, );\nEND_PROGRAM\n";
    assert_eq!(habits(text), ["3:10: TrailingComma", "4:9: TrailingComma"]);
    let p = pou(text);
    assert_eq!(p.body.len(), 2);
}

#[test]
fn an_empty_argument_is_left_out_of_the_call() {
    let text = "PROGRAM p\nt(IN := x, PT := , Q => q, ET => );\nn := F(A := , B := 1);\n\
                u(NOT Q => , CU := c);\nEND_PROGRAM\n";
    assert_eq!(
        habits(text),
        [
            "2:12: EmptyArgument { output: false }",
            "2:28: EmptyArgument { output: true }",
            "3:8: EmptyArgument { output: false }",
            "4:7: EmptyArgument { output: true }",
        ]
    );
    let p = pou(text);
    let args = |i: usize| -> Vec<String> {
        let e = match &p.body[i].kind {
            StmtKind::Call(e) => e,
            StmtKind::Assign { value, .. } => value,
            other => panic!("{other:?}"),
        };
        let ExprKind::Call { args, .. } = &e.kind else { panic!("{e:?}") };
        args.iter()
            .map(|a| match a {
                Arg::Input { name, .. } | Arg::Output { name, .. } => name.name.clone(),
                Arg::Positional(_) => "_".into(),
            })
            .collect()
    };
    assert_eq!(args(0), ["IN", "Q"]);
    assert_eq!(args(1), ["B"]);
    assert_eq!(args(2), ["CU"]);
    // a value that is missing elsewhere is still an error
    assert!(!errors("PROGRAM p\nt(IN := + );\nEND_PROGRAM\n").is_empty());
}

fn decls(text: &str) -> Vec<VarDecl> {
    let mut p = pou(&format!("PROGRAM p\nVAR\n{text}\nEND_VAR\nEND_PROGRAM"));
    p.vars.remove(0).decls
}

fn decl(text: &str) -> VarDecl {
    let mut all = decls(text);
    assert_eq!(all.len(), 1);
    all.remove(0)
}

#[test]
fn parses_edge_declarations() {
    let d = decl("start, stop : BOOL R_EDGE;");
    assert_eq!(d.edge, Some((Edge::Rising, sp(3, 20))));
    assert_eq!(decl("x : bool f_edge;").edge.map(|e| e.0), Some(Edge::Falling));
    assert_eq!(decl("x : BOOL := TRUE;").edge, None);
    // only after the type: elsewhere a name
    assert!(matches!(decl("R_EDGE : BOOL;").ty, TypeRef::Named(ref n) if n.is("BOOL")));
}

#[test]
fn parses_variable_declarations() {
    let d = decl("a, b : INT := 5;");
    let names: Vec<&str> = d.names.iter().map(|n| n.name.as_str()).collect();
    assert_eq!((names, d.span, d.names[1].span), (vec!["a", "b"], sp(3, 1), sp(3, 4)));
    assert!(matches!(d.ty, TypeRef::Named(ref n) if n.is("int")));
    assert!(matches!(d.init, Some(Init::Expr(ref e)) if sx(e) == "5"));
    for (text, loc) in [
        ("x AT %D00100 : INT;", "D00100"),
        ("x AT %P0040 : BOOL;", "P0040"),
        ("x AT %M0000 : BOOL;", "M0000"),
        ("x AT %D00010.3 : BOOL;", "D00010.3"),
        ("x AT %IX0.0 : BOOL;", "IX0.0"),
        ("x AT %QX0.1 : BOOL;", "QX0.1"),
        ("x AT %MW10 : WORD;", "MW10"),
        ("x AT %ID4 : DINT;", "ID4"),
    ] {
        let d = decl(text);
        let location = d.location.unwrap();
        assert_eq!((location.name.as_str(), location.span), (loc, sp(3, 6)), "{text}");
    }
}

#[test]
fn parses_types() {
    let ty = |text: &str| decl(&format!("x : {text};")).ty;
    assert!(matches!(ty("String"), TypeRef::String { len: None, span } if span == sp(3, 5)));
    assert!(matches!(ty("STRING[20]"), TypeRef::String { len: Some(ref n), .. } if sx(n) == "20"));
    assert!(matches!(ty("STRING(20)"), TypeRef::String { len: Some(ref n), .. } if sx(n) == "20"));
    let TypeRef::Array { dims, of, span } = ty("ARRAY [1..10, -5..N - 1] OF ARRAY [0..1] OF Point")
    else {
        panic!()
    };
    let dims: Vec<String> = dims.iter().map(|(a, b)| format!("{}..{}", sx(a), sx(b))).collect();
    assert_eq!((dims, span), (vec!["1..10".to_string(), "(- 5)..(- N 1)".to_string()], sp(3, 5)));
    let TypeRef::Array { of, .. } = *of else { panic!() };
    assert!(matches!(*of, TypeRef::Named(ref n) if n.is("point")));
    // `ARRAY [*, *] OF T` (IEC 61131-3 ed. 3): open dimensions, counted
    let TypeRef::OpenArray { rank, of, span } = ty("ARRAY [*, *] OF INT") else { panic!() };
    assert_eq!((rank, span), (2, sp(3, 5)));
    assert!(matches!(*of, TypeRef::Named(ref n) if n.is("INT")));
    assert!(matches!(ty("ARRAY[*] OF Point"), TypeRef::OpenArray { rank: 1, .. }));
    let TypeRef::Subrange { base, lo, hi, .. } = ty("INT (0..100)") else { panic!() };
    assert_eq!((base.name.as_str(), sx(&lo), sx(&hi)), ("INT", "0".into(), "100".into()));
    let TypeRef::Subrange { lo, .. } = ty("INT (-Lo..Hi)") else { panic!() };
    assert_eq!(sx(&lo), "(- Lo)");
    let TypeRef::Enum(def) = ty("(A, B := 5, C)") else { panic!() };
    let values: Vec<(String, Option<String>)> =
        def.values.iter().map(|(n, v)| (n.name.clone(), v.as_ref().map(sx))).collect();
    assert_eq!(values, [("A".into(), None), ("B".into(), Some("5".into())), ("C".into(), None)]);
    assert_eq!((def.base, def.span), (None, sp(3, 5)));
    let TypeRef::Enum(def) = ty("INT (A, B)") else { panic!() };
    assert_eq!((def.base.unwrap().name, def.values.len()), ("INT".to_string(), 2));
    let TypeRef::Enum(def) = ty("UINT (A := 1)") else { panic!() };
    assert_eq!(def.values.len(), 1);
}

#[test]
fn parses_initial_values() {
    let init = |text: &str| decl(&format!("x : T := {text};")).init.unwrap();
    let Init::Array { elems, span } = init("[1, 2, 3(0), 2(), -1, 2([1, 2])]") else { panic!() };
    assert_eq!((elems.len(), span), (6, sp(3, 10)));
    assert!(matches!(&elems[0], ArrayInit::One(Init::Expr(e)) if sx(e) == "1"));
    assert!(
        matches!(&elems[2], ArrayInit::Repeat { count, value: Some(Init::Expr(v)) } if sx(count) == "3" && sx(v) == "0")
    );
    assert!(matches!(&elems[3], ArrayInit::Repeat { value: None, .. }));
    assert!(matches!(&elems[4], ArrayInit::One(Init::Expr(e)) if sx(e) == "(- 1)"));
    assert!(matches!(&elems[5], ArrayInit::Repeat { value: Some(Init::Array { .. }), .. }));
    let Init::Struct { members, span } = init("(a := 1, b := TRUE, c := (d := [1, 2]), e := 'x')")
    else {
        panic!()
    };
    assert_eq!((members.len(), span), (4, sp(3, 10)));
    assert!(
        matches!(&members[2].1, Init::Struct { members, .. } if matches!(members[0].1, Init::Array { .. }))
    );
    // A parenthesised expression is no struct.
    assert!(matches!(init("(1 + 2) * 3"), Init::Expr(e) if sx(&e) == "(* (+ 1 2) 3)"));
    let Init::Array { elems, .. } = init("[(x := 1, y := 2), (x := 3, y := 4)]") else { panic!() };
    assert!(matches!(&elems[1], ArrayInit::One(Init::Struct { .. })));
}

#[test]
fn parses_an_enumerations_base_type_after_its_values() {
    // CODESYS's `(…) BYTE`, a default after it; a name followed by `:` is the next type
    let items = parse_ok("TYPE\n  E : (A, B) BYTE := B\n  F : (C, D)\n  G : INT;\nEND_TYPE");
    let defs: Vec<&TypeDef> = items
        .iter()
        .map(|i| match i {
            Item::Type(t) => &t.def,
            other => panic!("{other:?}"),
        })
        .collect();
    let TypeDef::Enum { def, init } = defs[0] else { panic!("{defs:?}") };
    assert!(def.base.as_ref().is_some_and(|b| b.is("BYTE")));
    assert!(init.as_ref().is_some_and(|i| i.is("B")));
    let TypeDef::Enum { def, .. } = defs[1] else { panic!("{defs:?}") };
    assert!(def.base.is_none());
    assert!(matches!(defs[2], TypeDef::Alias { .. }));
}

#[test]
fn parses_labels_and_jumps() {
    // a label is a statement of its own (no `;`), also right before an END_…; JMP is no
    // keyword: a variable may be called jmp
    let items = parse_ok(
        "PROGRAM P VAR jmp : INT; END_VAR\nagain: jmp := jmp + 1;\nIF jmp < 3 THEN JMP again; last: END_IF\nEND_PROGRAM",
    );
    let Item::Pou(p) = &items[0] else { panic!("{items:?}") };
    assert!(matches!(&p.body[0].kind, StmtKind::Label(l) if l.is("again")));
    assert_eq!(p.body[0].span, sp(2, 1));
    assert!(matches!(&p.body[1].kind, StmtKind::Assign { .. }));
    let StmtKind::If { branches, .. } = &p.body[2].kind else { panic!("{:?}", p.body[2]) };
    assert!(matches!(&branches[0].1[0].kind, StmtKind::Jump(l) if l.is("again")));
    assert!(matches!(&branches[0].1[1].kind, StmtKind::Label(l) if l.is("last")));
}

#[test]
fn parses_unions_as_codesys_writes_them() {
    // no `;` after END_UNION (a CODESYS habit), then a STRUCT holding the union
    let items = parse_ok(
        "TYPE\n  Bits : UNION\n    dw : DWORD;\n    b : ARRAY [0..3] OF BYTE;\n  END_UNION\n  Tagged : STRUCT tag : BYTE; v : Bits; END_STRUCT;\nEND_TYPE",
    );
    let Item::Type(bits) = &items[0] else { panic!("{items:?}") };
    let TypeDef::Union { members } = &bits.def else { panic!("{bits:?}") };
    let names: Vec<&str> = members.iter().map(|m| m.names[0].name.as_str()).collect();
    assert_eq!(names, ["dw", "b"]);
    assert!(matches!(&items[1], Item::Type(TypeDecl { def: TypeDef::Struct { .. }, .. })));
    assert_eq!(one_tok("end_union"), Tok::Kw(Kw::EndUnion));
}

#[test]
fn parses_type_blocks() {
    let items = parse_ok(
        "TYPE\n  Point : STRUCT\n    x, y : REAL := 0.0;\n    tag : STRING[8];\n  END_STRUCT;\n  Color : (Red, Green := 5, Blue) := Green;\n  Small : INT (A, B);\n  Speed : INT := 10;\n  Buf : ARRAY [0..9] OF INT := [10(0)];\n  Pct : INT (0..100) := 50;\n  Name : STRING(20);\nEND_TYPE\nTYPE Plain : (One, Two); END_TYPE",
    );
    let decls: Vec<TypeDecl> = items
        .into_iter()
        .map(|i| match i {
            Item::Type(t) => t,
            other => panic!("{other:?}"),
        })
        .collect();
    let names: Vec<&str> = decls.iter().map(|d| d.name.name.as_str()).collect();
    assert_eq!(names, ["Point", "Color", "Small", "Speed", "Buf", "Pct", "Name", "Plain"]);
    assert_eq!(decls[0].span, sp(2, 3));
    let TypeDef::Struct { members } = &decls[0].def else { panic!() };
    assert_eq!((members.len(), members[0].names.len()), (2, 2));
    let TypeDef::Enum { def, init } = &decls[1].def else { panic!() };
    assert_eq!((def.values.len(), init.as_ref().unwrap().name.as_str()), (3, "Green"));
    let TypeDef::Enum { def, init } = &decls[2].def else { panic!() };
    assert!(def.base.is_some() && init.is_none());
    assert!(matches!(&decls[3].def, TypeDef::Alias { ty: TypeRef::Named(_), init: Some(_) }));
    assert!(matches!(
        &decls[4].def,
        TypeDef::Alias { ty: TypeRef::Array { .. }, init: Some(Init::Array { .. }) }
    ));
    assert!(matches!(
        &decls[5].def,
        TypeDef::Alias { ty: TypeRef::Subrange { .. }, init: Some(_) }
    ));
    assert!(matches!(&decls[6].def, TypeDef::Alias { ty: TypeRef::String { .. }, init: None }));
    assert!(matches!(&decls[7].def, TypeDef::Enum { init: None, .. }));
}

// ----- CODESYS and TwinCAT habits -----

/// The habits a file's parse noted, as `line:col: habit`.
fn habits(text: &str) -> Vec<String> {
    let (file, diags) = parse_file(Path::new("t.st"), text);
    assert!(diags.is_empty(), "{text}\n{diags}");
    file.habits.iter().map(|n| format!("{}:{}: {:?}", n.span.line, n.span.col, n.habit)).collect()
}

#[test]
fn a_compound_statement_needs_no_semicolon_after_its_end() {
    let text = "PROGRAM p\nIF a THEN x := 1; END_IF\nCASE x OF 1: y := 2; END_CASE\n\
                FOR i := 1 TO 2 DO END_FOR\nWHILE a DO END_WHILE\n\
                REPEAT x := 1; UNTIL a END_REPEAT\nEND_PROGRAM\n";
    assert_eq!(
        habits(text),
        [
            "3:1: NoSemicolonAfterEnd(\"END_IF\")",
            "4:1: NoSemicolonAfterEnd(\"END_CASE\")",
            "5:1: NoSemicolonAfterEnd(\"END_FOR\")",
            "6:1: NoSemicolonAfterEnd(\"END_WHILE\")",
            "7:1: NoSemicolonAfterEnd(\"END_REPEAT\")",
        ]
    );
    assert_eq!(body("IF a THEN x := 1; END_IF\ny := 2;").len(), 2);
    // a simple statement still needs its `;`
    assert_eq!(body_errors("x := 1\nEND_IF;").len(), 1);
}

#[test]
fn a_type_declaration_needs_no_semicolon_before_end_type_or_the_next_type() {
    let text = "TYPE\nS : STRUCT a : INT; END_STRUCT\nE : (A, B)\nT : INT\nEND_TYPE\n";
    assert_eq!(
        habits(text),
        ["3:1: NoSemicolonAfterType", "4:1: NoSemicolonAfterType", "5:1: NoSemicolonAfterType"]
    );
    let items = parse_ok(text);
    assert_eq!(items.len(), 3);
}

#[test]
fn actions_are_read_inside_a_pou_and_at_the_top_level() {
    let text =
        "FUNCTION_BLOCK f\nVAR n : INT; END_VAR\nn := 1;\nACTION Reset:\n  n := 0;\nEND_ACTION\n\
                n := 2;\nEND_FUNCTION_BLOCK\nACTION Later: n := 5; END_ACTION\n\
                ACTION f.Named:\nEND_ACTION;\n";
    let items = parse_ok(text);
    let Item::Pou(pou) = &items[0] else { panic!("{items:?}") };
    assert_eq!(pou.body.len(), 2, "the statements around the action are the body");
    assert_eq!(pou.actions.len(), 1);
    assert!(pou.actions[0].name.is("Reset"));
    assert_eq!((pou.actions[0].span.line, pou.actions[0].end.line), (4, 6));
    let Item::Action { owner: None, action } = &items[1] else { panic!("{items:?}") };
    assert!(action.name.is("Later") && action.body.len() == 1);
    let Item::Action { owner: Some(owner), action } = &items[2] else { panic!("{items:?}") };
    assert!(owner.is("f") && action.name.is("Named") && action.body.is_empty());
}

#[test]
fn a_configuration_holds_resources_tasks_and_program_instances() {
    let text = "PROGRAM p END_PROGRAM\nCONFIGURATION Config0\n\
                VAR_GLOBAL g : INT; END_VAR\n\
                RESOURCE Res0 ON PLC\n\
                TASK task0(INTERVAL := T#20ms,PRIORITY := 0);\n\
                PROGRAM instance0 WITH task0 : p;\n\
                END_RESOURCE\n\
                PROGRAM loose : p;\n\
                END_CONFIGURATION\n";
    let items = parse_ok(text);
    let Item::Configuration(c) = &items[1] else { panic!("{items:?}") };
    assert!(c.name.is("Config0"));
    assert_eq!(c.globals.len(), 1);
    assert_eq!(c.resources.len(), 2, "the loose program makes a resource of its own, first");
    assert!(c.resources[0].name.is_none() && c.resources[0].programs[0].name.is("loose"));
    let res = &c.resources[1];
    assert!(res.name.as_ref().unwrap().is("Res0"));
    assert_eq!(res.tasks[0].properties.len(), 2);
    assert!(res.programs[0].task.as_ref().unwrap().is("task0") && res.programs[0].pou.is("p"));
    // `task`, `on` and `with` stay names outside a configuration
    assert_eq!(body("task := on AND with;").len(), 1);
}

#[test]
fn a_configuration_takes_direct_addresses_and_program_arguments() {
    let text = "PROGRAM p END_PROGRAM\nCONFIGURATION c\n\
                TASK trig(SINGLE := %IX0.1, PRIORITY := 1);\n\
                PROGRAM i WITH trig : p (speed := limit + 1, run := %IX0.2, done => %QX0.3, n => g);\n\
                PROGRAM j : p();\n\
                END_CONFIGURATION\n";
    let items = parse_ok(text);
    let Item::Configuration(c) = &items[1] else { panic!("{items:?}") };
    let res = &c.resources[0];
    let (key, value) = &res.tasks[0].properties[0];
    assert!(key.is("SINGLE"));
    let ConfigValue::Location(at) = value else { panic!("{value:?}") };
    assert_eq!((at.name.as_str(), at.span.col), ("IX0.1", 21));
    let args = &res.programs[0].args;
    let written: Vec<(&str, bool)> =
        args.iter().map(|a| (a.name.name.as_str(), a.output)).collect();
    assert_eq!(written, [("speed", false), ("run", false), ("done", true), ("n", true)]);
    assert!(
        matches!(&args[0].value, ConfigValue::Expr(e) if matches!(e.kind, ExprKind::Binary(..)))
    );
    assert!(matches!(&args[2].value, ConfigValue::Location(l) if l.name == "QX0.3"));
    assert!(res.programs[1].args.is_empty());
}

#[test]
fn var_config_entries_name_an_instance_path_an_address_and_a_type() {
    let text = "PROGRAM p END_PROGRAM\nCONFIGURATION c\n\
                PROGRAM i : p;\n\
                VAR_CONFIG\n\
                  i.lamp AT %QX0.1 : BOOL;\n\
                  i.fb.level : INT := 7;\n\
                END_VAR\n\
                END_CONFIGURATION\n";
    let items = parse_ok(text);
    let Item::Configuration(c) = &items[1] else { panic!("{items:?}") };
    assert_eq!(c.var_config.len(), 2);
    let path = |k: usize| c.var_config[k].path.iter().map(|i| i.name.clone()).collect::<Vec<_>>();
    assert_eq!(path(0), ["i", "lamp"]);
    assert_eq!(path(1), ["i", "fb", "level"]);
    assert_eq!(c.var_config[0].location.as_ref().unwrap().name, "QX0.1");
    assert!(c.var_config[1].location.is_none());
    assert!(c.var_config[0].init.is_none() && c.var_config[1].init.is_some());
    assert!(c.access.is_empty());
}

#[test]
fn partly_specified_addresses_and_partial_bit_access() {
    assert_eq!(toks("%I*"), [Tok::Location]);
    assert_eq!(toks("%QX* : BOOL"), [Tok::Location, Tok::P(P::Colon), Tok::Ident]);
    assert_eq!(toks("%D*").len(), 2, "a plcd device is never partial: `%D`, then `*`");
    assert_eq!(body("b := w.%X3;").len(), 1);
    let e = parse_expr("w.%X3").unwrap();
    assert!(matches!(e.kind, ExprKind::Bit(_, 3)), "{e:?}");
}

#[test]
fn partial_access_to_bytes_words_and_double_words() {
    let sx_of = |text: &str| sx(&parse_expr(text).unwrap());
    assert_eq!(sx_of("dw.%B2"), "(part dw B2)");
    assert_eq!(sx_of("lw.%w3"), "(part lw W3)");
    assert_eq!(sx_of("a[1].m.%D1"), "(part (. ([] a 1) m) D1)");
    // the lexer reads `%D1.` and `%W1.3` as one address each: the parser splits them
    assert_eq!(sx_of("lw.%D1.%B0"), "(part (part lw D1) B0)");
    // read, for the checker to say that no type has a long word part
    assert_eq!(sx_of("lw.%L0"), "(part lw L0)");
    assert_eq!(sx_of("lw.%W1.3"), "(bit (part lw W1) 3)");
    assert_eq!(sx_of("lw.%D1.%B0.%X7"), "(bit (part (part lw D1) B0) 7)");
    assert_eq!(sx_of("s.%B1.m"), "(. (part s B1) m)");
    assert!(parse_expr("w.%B").is_err(), "a part needs its number");
    assert!(parse_expr("w.%D1.").is_err(), "a dot needs what follows it");
}

#[test]
fn var_stat_var_inst_and_constant_inputs_are_noted() {
    let text = "FUNCTION_BLOCK f\nVAR_STAT a : INT; END_VAR\nVAR_INST b : INT; END_VAR\n\
                VAR_INPUT CONSTANT c : INT; END_VAR\nVAR_IN_OUT CONSTANT d : INT; END_VAR\n\
                END_FUNCTION_BLOCK\n";
    assert_eq!(habits(text), ["2:1: VarStat", "3:1: VarInst", "4:11: ConstantInput"]);
    let Some(Item::Pou(pou)) = parse_ok(text).into_iter().next() else { panic!() };
    let kinds: Vec<VarKind> = pou.vars.iter().map(|b| b.kind).collect();
    assert_eq!(kinds, [VarKind::Static, VarKind::Instance, VarKind::Input, VarKind::InOut]);
    assert!(pou.vars[2].constant && pou.vars[3].constant);
}

// ----- errors and recovery -----

#[test]
fn semicolons_are_required() {
    assert_eq!(
        body_errors("IF a THEN\n  x := 1\nEND_IF;"),
        ["4:1: expected `;` after the statement, found `END_IF`"]
    );
    assert_eq!(
        body_errors("x := 1\ny := 2;"),
        ["3:1: expected `;` after the statement, found `y`"]
    );
    assert_eq!(
        body_errors("REPEAT x := 1 UNTIL x END_REPEAT;"),
        ["2:15: expected `;` after the statement, found `UNTIL`"]
    );
    assert_eq!(
        errors("PROGRAM p VAR x : INT END_VAR END_PROGRAM"),
        ["1:23: expected `;` after the declaration, found `END_VAR`"]
    );
}

#[test]
fn missing_ends_are_reported_once_where_something_else_is() {
    assert_eq!(
        body_errors("IF a THEN\n  x := 1;\n"),
        ["5:1: `END_IF` expected to close the IF at line 2, found `END_PROGRAM`"]
    );
    assert_eq!(
        body_errors("WHILE a DO\n  IF b THEN\n    x := 1;\nEND_WHILE;"),
        ["5:1: `END_IF` expected to close the IF at line 3, found `END_WHILE`"]
    );
    // A misspelt end is the end.
    assert_eq!(
        body_errors("WHILE a DO\n  x := 1;\nEND_FOR;\ny := 2;"),
        ["4:1: `END_WHILE` expected to close the WHILE at line 2, found `END_FOR`"]
    );
    // Two missing ends: two errors.
    assert_eq!(
        body_errors("FOR i := 1 TO 2 DO\n  CASE i OF 1: x := 1;\n"),
        [
            "5:1: `END_CASE` expected to close the CASE at line 3, found `END_PROGRAM`",
            "5:1: `END_FOR` expected to close the FOR at line 2, found `END_PROGRAM`",
        ]
    );
    assert_eq!(
        errors("PROGRAM a\nx := 1;\nPROGRAM b\nEND_PROGRAM"),
        ["3:1: `END_PROGRAM` expected to close the PROGRAM at line 1, found `PROGRAM`"]
    );
    assert_eq!(
        errors("FUNCTION_BLOCK f\nVAR_INPUT\n  x : INT;\nx := 1;\nEND_FUNCTION_BLOCK"),
        ["4:1: `END_VAR` expected to close the VAR_INPUT at line 2, found `x`"]
    );
}

#[test]
fn stray_keywords_are_no_statements() {
    assert_eq!(
        body_errors("x := 1;\nEND_IF;\ny := 2;"),
        ["3:1: expected a statement, found `END_IF`"]
    );
    assert_eq!(body_errors("ELSE\ny := 2;"), ["2:1: expected a statement, found `ELSE`"]);
    assert_eq!(
        body_errors("y := 2;\nVAR x : INT; END_VAR\ny := 2;"),
        ["3:1: expected a statement, found `VAR`"]
    );
    assert_eq!(body_errors("x = 1;\ny := 2;"), ["2:3: expected `:=`, found `=`"]);
    assert_eq!(body_errors("x;"), ["2:2: expected `:=`, found `;`"]);
    assert_eq!(body_errors("5 := x;"), ["2:1: expected a statement, found `5`"]);
}

#[test]
fn recovers_inside_conditions() {
    assert_eq!(
        body_errors("IF a + THEN x := 1; END_IF;"),
        ["2:8: expected an expression, found `THEN`"]
    );
    assert_eq!(body_errors("IF a x := 1; END_IF;"), ["2:6: expected `THEN`, found `x`"]);
    assert_eq!(body_errors("WHILE a x := 1; END_WHILE;"), ["2:9: expected `DO`, found `x`"]);
    assert_eq!(body_errors("FOR i := 1 2 DO END_FOR;"), ["2:12: expected `TO`, found `2`"]);
    assert_eq!(body_errors("CASE a 1: x := 1; END_CASE;"), ["2:8: expected `OF`, found `1`"]);
    assert_eq!(
        body_errors("CASE a OF x := 1; END_CASE;"),
        ["2:11: expected a case label, found `x`"]
    );
    assert_eq!(body_errors("CASE a OF 1 x := 1; END_CASE;"), ["2:13: expected `:`, found `x`"]);
    assert_eq!(
        body_errors("REPEAT x := 1; UNTIL a END_WHILE;"),
        ["2:24: expected `END_REPEAT`, found `END_WHILE`"]
    );
    assert_eq!(body_errors("FOR 1 := 1 TO 2 DO END_FOR;"), ["2:5: expected a name, found `1`"]);
    assert_eq!(body_errors("IF (a THEN x := 1; END_IF;"), ["2:7: expected `)`, found `THEN`"]);
    assert_eq!(body_errors("IF a + ; x := 1; END_IF;"), ["2:8: expected an expression, found `;`"]);
}

#[test]
fn reports_declaration_errors() {
    let var = |text: &str| errors(&format!("PROGRAM p VAR\n{text}\nEND_VAR END_PROGRAM"));
    assert_eq!(var("x INT;"), ["2:3: expected `:`, found `INT`"]);
    assert_eq!(var("x : ;"), ["2:5: expected a type, found `;`"]);
    assert_eq!(var("x : ARRAY 1..2 OF INT;"), ["2:11: expected `[`, found `1`"]);
    assert_eq!(var("x : ARRAY [1] OF INT;"), ["2:13: expected `..`, found `]`"]);
    assert_eq!(var("x : ARRAY [1..2 OF INT;"), ["2:17: expected `,` or `]`, found `OF`"]);
    assert_eq!(var("x : ARRAY [1..2] INT;"), ["2:18: expected `OF`, found `INT`"]);
    // every dimension of an open array is `*`
    assert_eq!(
        var("x : ARRAY [*, 1..2] OF INT;"),
        ["2:15: expected `*` (every dimension of an `ARRAY [*, …]` is open), found `1`"]
    );
    assert_eq!(var("x : ARRAY [*] INT;"), ["2:15: expected `OF`, found `INT`"]);
    assert_eq!(var("x : STRING[10;"), ["2:14: expected `]`, found `;`"]);
    assert_eq!(var("x : (A, B;"), ["2:10: expected `,` or `)`, found `;`"]);
    // a function block's positional declaration arguments parse (`fb : T(1, 2)`); for an
    // enumeration the checker refuses them (golden enum-arguments)
    assert!(var("x : INT (1, 2);").is_empty());
    assert_eq!(var("x AT D0 : INT;"), ["2:6: expected an address `%…` after `AT`, found `D0`"]);
    assert_eq!(var("x, : INT;"), ["2:4: expected a name, found `:`"]);
    assert_eq!(
        var("5 : INT;\ny : INT;"),
        ["2:1: expected a variable name or `END_VAR`, found `5`"]
    );
    assert_eq!(var("x : INT := ;"), ["2:12: expected an expression, found `;`"]);
    assert_eq!(var("x : T := [1, 2;"), ["2:15: expected `,` or `]`, found `;`"]);
    assert_eq!(var("x : T := (a := 1 b := 2);"), ["2:18: expected `,` or `)`, found `b`"]);
    assert_eq!(var("x : T := (a := 1, 5 := 2);"), ["2:19: expected a name, found `5`"]);
    assert_eq!(var("x : T := [3(1];"), ["2:14: expected `)`, found `]`"]);
    let ty = |text: &str| errors(&format!("TYPE\n{text}\nEND_TYPE"));
    assert_eq!(ty("5 : INT;"), ["2:1: expected a type name or `END_TYPE`, found `5`"]);
    assert_eq!(
        ty("S : STRUCT 5; END_STRUCT;"),
        ["2:12: expected a member name or `END_STRUCT`, found `5`"]
    );
    assert_eq!(
        ty("S : STRUCT a : INT; END_STRUCT 5"),
        ["2:32: expected `;` after the declaration, found `5`"]
    );
    assert_eq!(
        ty("S : STRUCT a : INT;"),
        ["3:1: `END_STRUCT` expected to close the STRUCT at line 2, found `END_TYPE`"]
    );
    assert_eq!(ty("E : (A, B) := 5;"), ["2:15: expected a name, found `5`"]);
    assert_eq!(
        errors("TYPE A : INT;\nPROGRAM p END_PROGRAM"),
        ["2:1: `END_TYPE` expected to close the TYPE at line 1, found `PROGRAM`"]
    );
    assert_eq!(errors("x := 1;\nPROGRAM p END_PROGRAM"), ["1:1: expected `PROGRAM`, `FUNCTION`, `FUNCTION_BLOCK`, `TYPE`, `VAR_GLOBAL`, `ACTION`, `INTERFACE`, `CLASS` or `CONFIGURATION`, found `x`"]);
    assert_eq!(errors("PROGRAM 5 END_PROGRAM"), ["1:9: expected a name, found `5`"]);
}

#[test]
fn reports_every_error_of_a_file_once() {
    let text = "PROGRAM p\nVAR\n  a : INT\n  b : INT := 16#FG;\nEND_VAR\nIF a THEN\n  b := 'x\nc := 1 + ;\nd := T#5x;\nWHILE a DO\n  e := 1;\nEND_PROGRAM\n(* open";
    assert_eq!(
        errors(text),
        [
            "4:3: expected `;` after the declaration, found `b`",
            "4:14: `16#FG` is not a number",
            "7:8: unterminated string",
            "8:10: expected an expression, found `;`",
            "9:6: `T#5x` is not a duration: unknown unit `x`",
            "12:1: `END_WHILE` expected to close the WHILE at line 10, found `END_PROGRAM`",
            "12:1: `END_IF` expected to close the IF at line 6, found `END_PROGRAM`",
            "13:8: unterminated comment (opened at line 13)",
        ]
    );
}

#[test]
fn an_unterminated_string_hides_what_follows_it() {
    // The `;` is in the string: the missing `;` is the string's fault.
    assert_eq!(body_errors("x := 'abc;\ny := 1;"), ["2:6: unterminated string"]);
    // Only the next token is quiet.
    assert_eq!(
        body_errors("x := 'abc;\ny := 1\nz := 2;"),
        ["2:6: unterminated string", "4:1: expected `;` after the statement, found `z`"]
    );
}

#[test]
fn a_wrong_pou_end_closes_the_pou() {
    assert_eq!(
        errors("FUNCTION f : INT\nf := 1;\nEND_FUNCTION_BLOCK\nPROGRAM p END_PROGRAM"),
        ["3:1: `END_FUNCTION` expected to close the FUNCTION at line 1, found `END_FUNCTION_BLOCK`"]
    );
    // Inside a statement, the statement's end is missing; the POU's end is then fine.
    assert_eq!(
        errors("FUNCTION f : INT\nIF TRUE THEN f := 1;\nEND_FUNCTION"),
        ["3:1: `END_IF` expected to close the IF at line 2, found `END_FUNCTION`"]
    );
    assert_eq!(
        errors("PROGRAM p\nIF TRUE THEN x := 1;\nEND_FUNCTION"),
        [
            "3:1: `END_IF` expected to close the IF at line 2, found `END_FUNCTION`",
            "3:1: `END_PROGRAM` expected to close the PROGRAM at line 1, found `END_FUNCTION`",
        ]
    );
}

#[test]
fn an_unterminated_comment_hides_the_missing_ends() {
    assert_eq!(
        errors("PROGRAM p\nx := 1;\n(* the rest"),
        ["3:12: unterminated comment (opened at line 3)"]
    );
}

// ----- messages -----

#[test]
fn templates_are_distinct_and_well_formed() {
    let all = message_templates();
    let mut sorted = all.clone();
    sorted.sort();
    sorted.dedup();
    assert_eq!(sorted.len(), all.len());
    let calendar = crate::value::CalendarError::TEMPLATES.len();
    assert_eq!(all.len(), Want::ALL.len() + Closer::ALL.len() + 21 + calendar);
    for t in &all {
        assert!(
            t.starts_with(|c: char| !c.is_ascii_uppercase() || t.starts_with("WSTRING")),
            "{t}"
        );
        assert_eq!(t.matches('`').count() % 2, 0, "{t}");
    }
}

// ----- round trip of random expressions -----

/// The level of an expression for printing: a binary operator's, 8 for a unary one, 10 for
/// the rest.
fn level(e: &Expr) -> u8 {
    match &e.kind {
        ExprKind::Binary(op, ..) => op_level(*op),
        ExprKind::Unary(..) => 8,
        _ => 10,
    }
}

/// Prints with every node in parentheses.
fn print_full(e: &Expr) -> String {
    match &e.kind {
        ExprKind::Literal(l) => print_literal(l),
        ExprKind::Name(n) => n.name.clone(),
        ExprKind::Member(x, m) => format!("({}).{}", print_full(x), m.name),
        ExprKind::Index(x, i) => format!(
            "({})[{}]",
            print_full(x),
            i.iter().map(print_full).collect::<Vec<_>>().join(", ")
        ),
        ExprKind::Bit(x, b) => format!("({}).{b}", print_full(x)),
        ExprKind::Part(x, size, n) => format!("({}).%{}{n}", print_full(x), size.letter()),
        ExprKind::Deref(x) => format!("({})^", print_full(x)),
        ExprKind::Unary(op, x) => format!("({} ({}))", unary_text(*op), print_full(x)),
        ExprKind::Binary(op, l, r) => {
            format!("(({}) {} ({}))", print_full(l), binary_text(*op), print_full(r))
        }
        ExprKind::Call { callee, args } => {
            format!("({})({})", print_full(callee), print_args(args, print_full))
        }
        ExprKind::Assign(t, v) => format!("(({}) := ({}))", print_full(t), print_full(v)),
    }
}

/// Prints with the parentheses the precedence table needs.
fn print_min(e: &Expr) -> String {
    let wrap = |x: &Expr, yes: bool| {
        if yes {
            format!("({})", print_min(x))
        } else {
            print_min(x)
        }
    };
    let postfix_base = |x: &Expr| wrap(x, level(x) < 10 || matches!(x.kind, ExprKind::Literal(_)));
    match &e.kind {
        ExprKind::Literal(l) => print_literal(l),
        ExprKind::Name(n) => n.name.clone(),
        ExprKind::Member(x, m) => format!("{}.{}", postfix_base(x), m.name),
        ExprKind::Index(x, i) => {
            format!(
                "{}[{}]",
                postfix_base(x),
                i.iter().map(print_min).collect::<Vec<_>>().join(", ")
            )
        }
        ExprKind::Bit(x, b) => format!("{}.{b}", postfix_base(x)),
        ExprKind::Part(x, size, n) => format!("{}.%{}{n}", postfix_base(x), size.letter()),
        ExprKind::Deref(x) => format!("{}^", postfix_base(x)),
        ExprKind::Unary(op, x) => format!("{} {}", unary_text(*op), wrap(x, level(x) < 8)),
        ExprKind::Binary(op, l, r) => {
            let lv = op_level(*op);
            // Left-associative: the same level needs parentheses on the right only; both
            // operands of `**` take theirs around a unary operator.
            let (left, right) = if *op == BinaryOp::Pow {
                (level(l) < 10, level(r) < 10)
            } else {
                (level(l) < lv, level(r) <= lv)
            };
            format!("{} {} {}", wrap(l, left), binary_text(*op), wrap(r, right))
        }
        ExprKind::Call { callee, args } => {
            format!("{}({})", postfix_base(callee), print_args(args, print_min))
        }
        ExprKind::Assign(t, v) => format!("({} := {})", print_min(t), print_min(v)),
    }
}

fn print_args(args: &[Arg], print: fn(&Expr) -> String) -> String {
    let all: Vec<String> = args
        .iter()
        .map(|a| match a {
            Arg::Positional(x) => print(x),
            Arg::Input { name, value } => format!("{} := {}", name.name, print(value)),
            Arg::Output { name, target, negated } => {
                format!("{}{} => {}", if *negated { "NOT " } else { "" }, name.name, print(target))
            }
        })
        .collect();
    all.join(", ")
}

fn print_literal(l: &Literal) -> String {
    match l {
        Literal::Int(n) => n.to_string(),
        Literal::Based(n) => format!("16#{n:X}"),
        Literal::Real(x) => format!("{x:?}"),
        Literal::Bool(b) => if *b { "TRUE" } else { "FALSE" }.to_string(),
        Literal::Time(ns) => format!("T#{ns}ns"),
        Literal::Calendar(cal, count) => {
            crate::value::format(&crate::value::ValueType::Calendar(*cal), *count)
        }
        Literal::String(s) => format!("'{s}'"),
        Literal::WString(s) => format!("\"{s}\""),
        Literal::Typed { ty, value } => format!("{}#{}", ty.name, print_min(value)),
    }
}

fn node(kind: ExprKind) -> Expr {
    Expr { kind, span: Span::default() }
}

fn name(n: &str) -> Ident {
    Ident { name: n.to_string(), span: Span::default() }
}

fn leaf() -> impl Strategy<Value = Expr> {
    prop_oneof![
        prop::sample::select(vec!["a", "b", "x1", "speed_sp", "_t"])
            .prop_map(|n| node(ExprKind::Name(name(n)))),
        (0u128..100_000).prop_map(|n| node(ExprKind::Literal(Literal::Int(n)))),
        prop::sample::select(vec![0.5, 1.0, 2.25, 1e20, 3.5e-7])
            .prop_map(|x| node(ExprKind::Literal(Literal::Real(x)))),
        any::<bool>().prop_map(|b| node(ExprKind::Literal(Literal::Bool(b)))),
        (0i128..1_000_000).prop_map(|ns| node(ExprKind::Literal(Literal::Time(ns)))),
        "[a-z ]{0,5}".prop_map(|s| node(ExprKind::Literal(Literal::String(s)))),
        (0u128..100).prop_map(|n| node(ExprKind::Literal(Literal::Typed {
            ty: name("INT"),
            value: Box::new(node(ExprKind::Literal(Literal::Int(n)))),
        }))),
    ]
}

const BINARY: [BinaryOp; 17] = [
    BinaryOp::Or,
    BinaryOp::OrElse,
    BinaryOp::Xor,
    BinaryOp::And,
    BinaryOp::AndThen,
    BinaryOp::Eq,
    BinaryOp::Ne,
    BinaryOp::Lt,
    BinaryOp::Le,
    BinaryOp::Gt,
    BinaryOp::Ge,
    BinaryOp::Add,
    BinaryOp::Sub,
    BinaryOp::Mul,
    BinaryOp::Div,
    BinaryOp::Mod,
    BinaryOp::Pow,
];

fn expr_tree() -> impl Strategy<Value = Expr> {
    leaf().prop_recursive(6, 48, 3, |inner| {
        prop_oneof![
            4 => (prop::sample::select(BINARY.to_vec()), inner.clone(), inner.clone())
                .prop_map(|(op, l, r)| node(ExprKind::Binary(op, Box::new(l), Box::new(r)))),
            2 => (prop::sample::select(vec![UnaryOp::Neg, UnaryOp::Plus, UnaryOp::Not]), inner.clone())
                .prop_map(|(op, x)| node(ExprKind::Unary(op, Box::new(x)))),
            1 => inner.clone().prop_map(|x| node(ExprKind::Member(Box::new(x), name("m")))),
            1 => (inner.clone(), 0u8..64).prop_map(|(x, b)| node(ExprKind::Bit(Box::new(x), b))),
            1 => (inner.clone(), prop::sample::select(vec![PartSize::Byte, PartSize::Word, PartSize::DWord, PartSize::LWord]), 0u8..8)
                .prop_map(|(x, size, n)| node(ExprKind::Part(Box::new(x), size, n))),
            1 => (inner.clone(), prop::collection::vec(inner.clone(), 1..3))
                .prop_map(|(x, i)| node(ExprKind::Index(Box::new(x), i))),
            1 => (inner.clone(), prop::collection::vec(inner.clone(), 0..3), inner.clone(), inner)
                .prop_map(|(f, pos, input, output)| {
                    let mut args: Vec<Arg> = pos.into_iter().map(Arg::Positional).collect();
                    args.push(Arg::Input { name: name("IN"), value: input });
                    args.push(Arg::Output { name: name("Q"), target: output, negated: true });
                    node(ExprKind::Call { callee: Box::new(f), args })
                }),
        ]
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(512))]

    #[test]
    fn printed_expressions_parse_back(e in expr_tree()) {
        let want = sx(&e);
        let full = print_full(&e);
        let min = print_min(&e);
        let parsed_full = parse_expr(&full).map_err(|err| format!("{full}: {err:?}"));
        let parsed_min = parse_expr(&min).map_err(|err| format!("{min}: {err:?}"));
        prop_assert_eq!(sx(&parsed_full.unwrap()), want.clone(), "{}", full);
        prop_assert_eq!(sx(&parsed_min.unwrap()), want, "{}", min);
        prop_assert!(min.matches('(').count() <= full.matches('(').count());
    }
}

// ----- size -----

/// A 10,000-line program: one FUNCTION_BLOCK and a PROGRAM of blocks of statements.
fn generated(lines: usize) -> String {
    let mut text = String::from(
        "TYPE Point : STRUCT x, y : REAL; END_STRUCT; END_TYPE\nFUNCTION_BLOCK Acc\nVAR_INPUT v : DINT; END_VAR\nVAR_OUTPUT sum : DINT; END_VAR\nsum := sum + v;\nEND_FUNCTION_BLOCK\nPROGRAM Big\nVAR\n  i, n : DINT;\n  pts : ARRAY [0..99] OF Point;\n  acc : Acc;\nEND_VAR\n",
    );
    let mut k = 0;
    while text.lines().count() < lines - 1 {
        text.push_str(&format!(
            "(* block {k} *)\nIF n MOD {m} = 0 AND NOT (i > {k}) THEN\n  n := n + {k} * 2 - i / 3;\nELSIF i <= 16#FF THEN\n  pts[i MOD 100].x := REAL#1.5 * pts[0].y ** 2;\nELSE\n  acc(v := n, sum => i);\nEND_IF;\nFOR i := 0 TO 99 BY 1 DO\n  CASE i OF\n    0, 2..5: n := -n;\n  ELSE\n    n := n XOR i;\n  END_CASE;\nEND_FOR;\nWHILE n > 1000 DO n := n / 2; END_WHILE;\nREPEAT n := n + 1; UNTIL n >= 0 END_REPEAT;\n",
            m = k % 7 + 2
        ));
        k += 1;
    }
    text.push_str("END_PROGRAM\n");
    text
}

#[test]
fn a_ten_thousand_line_file_parses_without_errors() {
    let text = generated(10_000);
    assert!(text.lines().count() >= 10_000);
    let (file, diags) = parse_file(Path::new("big.st"), &text);
    assert!(diags.is_empty(), "{diags}");
    assert_eq!(file.items.len(), 3);
    let Item::Pou(big) = &file.items[2] else { panic!() };
    assert!(big.body.len() > 2000);
}

/// Found by the fuzzer (tests/fuzz, target `st`): a statement keyword where a CASE label
/// belongs made the CASE loop go round for ever, one diagnostic a turn.
#[test]
fn a_statement_where_a_case_label_belongs_ends() {
    for stmt in ["CONTINUE;", "EXIT;", "RETURN;", "IF", "CONTINUE", "1, WHILE"] {
        let errors = body_errors(&format!("CASE {stmt}\nEND_CASE;"));
        assert!(!errors.is_empty() && errors.len() < 6, "{stmt}: {errors:?}");
    }
    let errors = body_errors("CASE x OF\n    CONTINUE;\nEND_CASE;");
    assert_eq!(errors, ["3:5: expected a case label, found `CONTINUE`"]);
}

#[test]
fn var_access_in_a_configuration_and_a_program() {
    let text = "PROGRAM main\n\
                VAR n : INT; END_VAR\n\
                VAR_ACCESS\n\
                  count : main.n : INT READ_ONLY;\n\
                  raw : n : INT;\n\
                END_VAR\n\
                n := n + 1;\n\
                END_PROGRAM\n\
                CONFIGURATION c\n\
                RESOURCE STATION_1 ON PLC\n\
                  PROGRAM P1 : main;\n\
                END_RESOURCE\n\
                VAR_ACCESS\n\
                  ABLE : STATION_1.%IX1.1 : BOOL READ_ONLY;\n\
                  BAKER : STATION_1.P1.x : UINT READ_WRITE;\n\
                  CORNER : P1.m[2, -1].pos[0][1] : INT;\n\
                END_VAR\n\
                END_CONFIGURATION\n";
    let items = parse_ok(text);
    let Item::Pou(main) = &items[0] else { panic!("{items:?}") };
    let path =
        |a: &crate::st::ast::AccessDecl| a.path.iter().map(|i| i.name.clone()).collect::<Vec<_>>();
    assert_eq!(main.access.len(), 2);
    assert_eq!(main.access[0].name.name, "count");
    assert_eq!(path(&main.access[0]), ["main", "n"]);
    assert!(!main.access[0].read_write && !main.access[1].read_write, "READ_ONLY by default");
    assert_eq!(main.body.len(), 1);
    let Item::Configuration(c) = &items[1] else { panic!("{items:?}") };
    assert_eq!(c.access.len(), 3);
    assert_eq!(path(&c.access[0]), ["STATION_1", "%IX1.1"]);
    assert_eq!(path(&c.access[1]), ["STATION_1", "P1", "x"]);
    assert!(c.access[1].read_write);
    // subscripts: per part, each bracket's expressions
    assert_eq!(path(&c.access[2]), ["P1", "m", "pos"]);
    let counts: Vec<Vec<usize>> =
        c.access[2].subscripts.iter().map(|g| g.iter().map(Vec::len).collect()).collect();
    assert_eq!(counts, [vec![], vec![2], vec![1, 1]]);
}

// ----- conditional pragmas -----

/// The names of `text`'s tokens with their places, `defines` defined.
fn kept(text: &str, defines: &[&str]) -> Vec<String> {
    let defines: Vec<String> = defines.iter().map(|d| d.to_string()).collect();
    let lexed = super::lex::lex_with(text, &defines);
    lexed
        .tokens
        .iter()
        .filter(|t| t.kind == Tok::Ident)
        .map(|t| {
            format!("{}:{}:{}", &text[t.start as usize..t.end as usize], t.span.line, t.span.col)
        })
        .collect()
}

fn cond_errors(text: &str) -> Vec<String> {
    super::lex::lex_with(text, &[])
        .errors
        .iter()
        .map(|(s, m)| format!("{}:{}: {m}", s.line, s.col))
        .collect()
}

#[test]
fn conditional_pragmas_keep_one_branch_and_the_places_of_what_follows() {
    let text =
        "{IF defined (a)}\nx\n{ELSIF defined (b) AND NOT defined (c)}\ny\n{ELSE}\nz\n{END_IF} w";
    assert_eq!(kept(text, &[]), ["z:6:1", "w:7:10"]);
    assert_eq!(kept(text, &["A"]), ["x:2:1", "w:7:10"], "names are case-insensitive");
    assert_eq!(kept(text, &["b"]), ["y:4:1", "w:7:10"]);
    assert_eq!(kept(text, &["b", "c"]), ["z:6:1", "w:7:10"]);
    // nested, inside a left-out branch: nothing of it, whatever it says
    let text = "{IF defined (a)}{IF NOT defined (a)}x{ELSE}y{END_IF}{ELSE}z{END_IF}";
    assert_eq!(kept(text, &[]), ["z:1:59"]);
    assert_eq!(kept(text, &["a"]), ["y:1:44"]);
    // {define} and {undefine} from their place on; left out, they define nothing
    let text = "{IF defined (a)}{define b}{END_IF}{define c}{undefine c}\
                {IF defined (b) OR defined (c)}x{ELSE}y{END_IF}";
    assert_eq!(kept(text, &[]), ["y:1:95"]);
    // what looks like a pragma in a comment or a string of a left-out branch is theirs
    let text = "{IF defined (a)} (* {END_IF} *) '{END_IF}' x {END_IF} y";
    assert_eq!(kept(text, &[]), ["y:1:55"]);
    // and a left-out branch's lexical errors are not reported
    assert!(cond_errors("{IF defined (a)} 16#G $ {END_IF}").is_empty());
    let text = "VAR_GLOBAL {define x} g : INT; END_VAR\n";
    assert_eq!(habits(text), ["1:12: ConditionalPragma"]);
}

#[test]
fn conditional_pragmas_report_what_plcd_cannot_read() {
    assert_eq!(cond_errors("{define}"), ["1:1: `{define}` needs a name: `{define name}`"]);
    assert_eq!(cond_errors("x {END_IF}"), ["1:3: `{END_IF}` without an `{IF}` open"]);
    assert_eq!(
        cond_errors("{IF defined (a)}{ELSE}{ELSIF defined (b)}{END_IF}"),
        ["1:23: `{ELSIF}` after the `{ELSE}` of its `{IF}`"]
    );
    assert_eq!(
        cond_errors("{IF defined (a) AND}{END_IF}"),
        ["1:1: expected a condition: `defined (name)`, with NOT, AND, OR and parentheses"]
    );
    let unsupported = |predicate: &str| {
        format!("1:1: `{predicate}` is not supported in a conditional pragma: plcd tests `defined (name)` of `{{define}}` and `[st] defines`")
    };
    assert_eq!(cond_errors("{IF hasvalue (a, '1')}{END_IF}"), [unsupported("hasvalue")]);
    assert_eq!(
        cond_errors("{IF defined (variable: x)}{END_IF}"),
        [unsupported("defined (variable: …)")]
    );
    assert_eq!(
        cond_errors("{IF defined (IsLittleEndian)}{END_IF}"),
        [unsupported("defined (IsLittleEndian)")]
    );
    assert_eq!(cond_errors("\n  {IF defined (a)}\nx"), ["2:3: `{IF}` without its `{END_IF}`"]);
    // other pragmas are no conditions
    assert!(cond_errors("{attribute 'qualified_only'} {warning 'x'} {IFX}").is_empty());
}
