//! Parse: program text into lines of tokens with their columns. Knows nothing of mnemonics;
//! it only strips comments and splits on white space (and commas, which some engineers write
//! between operands).

/// A word of a source line and its 1-based column.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Token<'a> {
    pub text: &'a str,
    pub col: u32,
}

/// A line that holds an instruction.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SourceLine<'a> {
    /// 1-based line number.
    pub line: u32,
    pub tokens: Vec<Token<'a>>,
}

/// Splits `source` into instruction lines; blank and comment-only lines are dropped.
pub fn parse(source: &str) -> Vec<SourceLine<'_>> {
    let mut lines = Vec::new();
    for (index, raw) in source.lines().enumerate() {
        let code = strip_comment(raw);
        let tokens = tokenize(code);
        if !tokens.is_empty() {
            lines.push(SourceLine { line: index as u32 + 1, tokens });
        }
    }
    lines
}

fn strip_comment(line: &str) -> &str {
    let semicolon = line.find(';');
    let slashes = line.find("//");
    let cut = match (semicolon, slashes) {
        (Some(a), Some(b)) => a.min(b),
        (Some(a), None) | (None, Some(a)) => a,
        (None, None) => line.len(),
    };
    &line[..cut]
}

fn tokenize(code: &str) -> Vec<Token<'_>> {
    let mut tokens = Vec::new();
    let mut start: Option<usize> = None;
    let is_separator = |c: char| c.is_whitespace() || c == ',';
    for (offset, c) in code.char_indices() {
        match (start, is_separator(c)) {
            (None, false) => start = Some(offset),
            (Some(s), true) => {
                tokens.push(token(code, s, offset));
                start = None;
            }
            _ => {}
        }
    }
    if let Some(s) = start {
        tokens.push(token(code, s, code.len()));
    }
    tokens
}

fn token(code: &str, start: usize, end: usize) -> Token<'_> {
    let col = code[..start].chars().count() as u32 + 1;
    Token { text: &code[start..end], col }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tokens_carry_columns() {
        let lines = parse("  LOAD P0000 ; start\n\n// nothing\nMOV 5,\tD00010\n");
        assert_eq!(lines.len(), 2);
        assert_eq!(lines[0].line, 1);
        assert_eq!(
            lines[0].tokens,
            vec![Token { text: "LOAD", col: 3 }, Token { text: "P0000", col: 8 }]
        );
        assert_eq!(lines[1].line, 4);
        let texts: Vec<_> = lines[1].tokens.iter().map(|t| (t.text, t.col)).collect();
        assert_eq!(texts, vec![("MOV", 1), ("5", 5), ("D00010", 8)]);
    }

    #[test]
    fn both_comment_styles() {
        assert!(parse("; all comment\n   // too").is_empty());
        assert_eq!(parse("OUT M0000// c").len(), 1);
        assert_eq!(parse("OUT M0000// c")[0].tokens.len(), 2);
    }

    #[test]
    fn columns_count_characters_not_bytes() {
        let lines = parse("ÄÖ LOAD");
        assert_eq!(lines[0].tokens[1].col, 4);
    }
}
