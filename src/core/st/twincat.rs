//! TwinCAT 3's source files (`.TcPOU`, `.TcDUT`, `.TcGVL`) read as Structured Text.
//!
//! TwinCAT keeps each POU, type or global list in an XML file whose ST sits in CDATA sections:
//! a POU's `<Declaration>` (its header and VAR blocks, without the `END_…`) and its
//! `<Implementation><ST>` body, and the same for each of its `<Action>`s; a DUT's or a GVL's
//! `<Declaration>` holds the whole `TYPE … END_TYPE` or `VAR_GLOBAL … END_VAR`.
//!
//! [`st_text`] turns such a file into ST text *with the file's own lines and columns*: every
//! character outside the CDATA sections becomes a space (line breaks stay), and the `END_…` a
//! POU needs is written on a line that held only XML after its last section. The parser and
//! the compiler then report every error at its place in the `.TcPOU` file itself.
//!
//! A `]]>` in the ST (a string `']]>'`) cannot stand inside a CDATA section: TwinCAT ends the
//! section after `]]` and opens the next one before `>` (`']]]]><![CDATA[>'`). Such adjacent
//! sections are one text: the `]]><![CDATA[` between them is dropped, not blanked (a blank
//! would land inside the string), and as many spaces are written at the end of that line, so
//! only the columns after the join on that one line move, by 12.

use std::ops::Range;

use crate::st::ast::Span;

/// Why a TwinCAT file is not read, at its place in the file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct XmlError {
    pub span: Span,
    pub message: String,
}

/// `xml` parsed, its root element checked to be `<root>`: `what` names the kind of file the
/// error says it is not (`"a TwinCAT source"`). The `.plcproj` reader shares it
/// (`crate::st::plcproj`).
pub(crate) fn parse_rooted<'x>(
    xml: &'x str,
    root: &str,
    what: &str,
) -> Result<roxmltree::Document<'x>, XmlError> {
    let doc = roxmltree::Document::parse(xml).map_err(|e| {
        let pos = e.pos();
        XmlError {
            span: Span { line: pos.row, col: pos.col },
            message: format!("not valid XML: {e}"),
        }
    })?;
    let found = doc.root_element();
    if found.tag_name().name() != root {
        return Err(XmlError {
            span: span_at(&doc, found.range().start),
            message: format!("`<{}>` is not {what}: `<{root}>` expected", found.tag_name().name()),
        });
    }
    Ok(doc)
}

/// The line and column of the byte at `pos` of `doc`'s text.
pub(crate) fn span_at(doc: &roxmltree::Document<'_>, pos: usize) -> Span {
    let p = doc.text_pos_at(pos);
    Span { line: p.row, col: p.col }
}

/// The Structured Text of a TwinCAT source file, line for line and column for column.
pub fn st_text(xml: &str) -> Result<String, XmlError> {
    let doc = parse_rooted(xml, "TcPlcObject", "a TwinCAT source")?;
    let at = |pos: usize| span_at(&doc, pos);
    let root = doc.root_element();
    // The CDATA sections to keep, and the keywords to write among the blanks.
    let mut keep: Vec<Range<usize>> = Vec::new();
    let mut words: Vec<(usize, String)> = Vec::new();
    for object in root.children().filter(|n| n.is_element()) {
        match object.tag_name().name() {
            // a POU, or an interface (`.TcIO`), whose methods and properties are alike
            "POU" | "Itf" => {
                let (before, words_before) = (keep.len(), words.len());
                collect_pou(object, xml, &mut keep, &mut words, &at)?;
                let header = keep.get(before).map(|r| &xml[r.clone()]).unwrap_or("");
                let Some(end) = pou_end(header) else {
                    return Err(XmlError {
                        span: at(object.range().start),
                        message: "the POU's declaration does not start with PROGRAM, FUNCTION, FUNCTION_BLOCK or INTERFACE".to_string(),
                    });
                };
                // on the line after its last section or action end, a line of XML only
                let last = keep.last().map_or(object.range().start, |r| r.end);
                let last = words[words_before..].iter().map(|(at, _)| *at).fold(last, usize::max);
                let next_line = xml[last..].find('\n').map_or(xml.len(), |n| last + n + 1);
                words.push((next_line, end.to_string()));
            }
            "DUT" | "GVL" => {
                if let Some(decl) = child(object, "Declaration") {
                    keep.extend(sections(decl, xml));
                }
            }
            other => {
                return Err(XmlError {
                    span: at(object.range().start),
                    message: format!(
                    "`<{other}>` is not read: a TwinCAT source holds a POU, an Itf, a DUT or a GVL"
                ),
                })
            }
        }
    }
    words.sort_by_key(|(at, _)| *at);
    keep.sort_by_key(|r| r.start);
    let joins: Vec<Range<usize>> = keep
        .windows(2)
        .filter(|pair| &xml[pair[0].end..pair[1].start] == CDATA_JOIN)
        .map(|pair| pair[0].end..pair[1].start)
        .collect();
    Ok(blank_outside(xml, &keep, &joins, &words))
}

/// The name of the global variable list a `.TcGVL` file holds (`<GVL Name="GVL_Param">`),
/// which qualifies its variables; `None` for another file, or XML that does not parse.
pub fn gvl_name(xml: &str) -> Option<String> {
    let doc = roxmltree::Document::parse(xml).ok()?;
    let gvl =
        doc.root_element().children().find(|n| n.is_element() && n.tag_name().name() == "GVL")?;
    gvl.attribute("Name").filter(|n| !n.is_empty()).map(str::to_string)
}

const CDATA_OPEN: &str = "<![CDATA[";
const CDATA_CLOSE: &str = "]]>";
/// What separates two CDATA sections TwinCAT wrote for one text holding `]]>`.
const CDATA_JOIN: &str = "]]><![CDATA[";

/// The first child element named `name`.
fn child<'a, 'i>(node: roxmltree::Node<'a, 'i>, name: &str) -> Option<roxmltree::Node<'a, 'i>> {
    node.children().find(|n| n.is_element() && n.tag_name().name() == name)
}

/// The contents of the CDATA sections directly inside `node`: read from the XML between its
/// tags, children elements left out (an XML reader merges adjacent sections into one text
/// node, and roxmltree's gives the place of the first only).
fn sections(node: roxmltree::Node<'_, '_>, xml: &str) -> Vec<Range<usize>> {
    let range = node.range();
    let Some(inner) = xml[range.clone()].find('>').map(|n| range.start + n + 1) else {
        return Vec::new();
    };
    let children: Vec<Range<usize>> =
        node.children().filter(|n| n.is_element()).map(|n| n.range()).collect();
    let end = closing_tag(node, xml).max(inner);
    let mut out = Vec::new();
    let mut from = inner;
    while let Some(open) = xml[from..end].find(CDATA_OPEN) {
        let start = from + open + CDATA_OPEN.len();
        let Some(close) = xml[start..end].find(CDATA_CLOSE) else { break };
        from = start + close + CDATA_CLOSE.len();
        if !children.iter().any(|c| c.contains(&start)) {
            out.push(start..start + close);
        }
    }
    out
}

/// A POU's declaration, its body, its actions (each written `ACTION Name: … END_ACTION` over its
/// XML tags), its methods (`<Method>`: a declaration `METHOD …` and a body; `END_METHOD` written
/// over its closing tag) and properties (`<Property>`: a declaration `PROPERTY …`, then `<Get>`
/// and `<Set>`, each a declaration and a body, written `GET … END_GET`, `SET … END_SET`; then
/// `END_PROPERTY`). Its transitions are refused at their place.
fn collect_pou(
    pou: roxmltree::Node<'_, '_>,
    xml: &str,
    keep: &mut Vec<Range<usize>>,
    words: &mut Vec<(usize, String)>,
    at: &dyn Fn(usize) -> Span,
) -> Result<(), XmlError> {
    if let Some(decl) = child(pou, "Declaration") {
        keep.extend(sections(decl, xml));
    }
    body(pou, xml, keep, at)?;
    for member in pou.children().filter(|n| n.is_element()) {
        match member.tag_name().name() {
            "Action" => {
                let name = member.attribute("Name").unwrap_or_default();
                let range = member.range();
                words.push((range.start, format!("ACTION {name}:")));
                body(member, xml, keep, at)?;
                // over `</Action>` (or the end of an empty `<Action/>`)
                let close = xml[range.clone()].rfind("</").map_or(range.end, |n| range.start + n);
                words.push((close, "END_ACTION".to_string()));
            }
            "Method" => {
                if let Some(decl) = child(member, "Declaration") {
                    keep.extend(sections(decl, xml));
                }
                body(member, xml, keep, at)?;
                words.push((closing_tag(member, xml), "END_METHOD".to_string()));
            }
            "Property" => {
                if let Some(decl) = child(member, "Declaration") {
                    keep.extend(sections(decl, xml));
                }
                for accessor in member.children().filter(|n| n.is_element()) {
                    let word = match accessor.tag_name().name() {
                        "Get" => "GET",
                        "Set" => "SET",
                        _ => continue,
                    };
                    words.push((accessor.range().start, word.to_string()));
                    if let Some(decl) = child(accessor, "Declaration") {
                        keep.extend(sections(decl, xml));
                    }
                    body(accessor, xml, keep, at)?;
                    words.push((closing_tag(accessor, xml), format!("END_{word}")));
                }
                words.push((closing_tag(member, xml), "END_PROPERTY".to_string()));
            }
            "Transition" => {
                let what = member.tag_name().name();
                return Err(XmlError {
                    span: at(member.range().start),
                    message: format!("a POU's `<{what}>` is not read from TwinCAT files"),
                });
            }
            _ => {}
        }
    }
    keep.sort_by_key(|r| r.start);
    Ok(())
}

/// Where an element's closing tag starts (the end of an empty `<X/>`).
fn closing_tag(node: roxmltree::Node<'_, '_>, xml: &str) -> usize {
    let range = node.range();
    xml[range.clone()].rfind("</").map_or(range.end, |n| range.start + n)
}

/// The ST body of `<Implementation>`; a graphical body is refused at its place.
fn body(
    owner: roxmltree::Node<'_, '_>,
    xml: &str,
    keep: &mut Vec<Range<usize>>,
    at: &dyn Fn(usize) -> Span,
) -> Result<(), XmlError> {
    let Some(implementation) = child(owner, "Implementation") else { return Ok(()) };
    for language in implementation.children().filter(|n| n.is_element()) {
        match language.tag_name().name() {
            "ST" => keep.extend(sections(language, xml)),
            other => {
                return Err(XmlError {
                    span: at(language.range().start),
                    message: format!(
                        "a `<{other}>` body is graphical: only Structured Text (`<ST>`) bodies are read"
                    ),
                })
            }
        }
    }
    Ok(())
}

/// The `END_…` of the POU whose declaration is `header`: by its first keyword, after white
/// space, comments and pragmas.
fn pou_end(header: &str) -> Option<&'static str> {
    let mut rest = header;
    loop {
        rest = rest.trim_start();
        if let Some(after) = rest.strip_prefix("(*") {
            rest = after.split_once("*)").map_or("", |(_, r)| r);
        } else if let Some(after) = rest.strip_prefix("//") {
            rest = after.split_once('\n').map_or("", |(_, r)| r);
        } else if let Some(after) = rest.strip_prefix('{') {
            rest = after.split_once('}').map_or("", |(_, r)| r);
        } else {
            break;
        }
    }
    let word: String =
        rest.chars().take_while(|c| c.is_ascii_alphanumeric() || *c == '_').collect();
    match word.to_ascii_uppercase().as_str() {
        "PROGRAM" => Some("END_PROGRAM"),
        "FUNCTION" => Some("END_FUNCTION"),
        "FUNCTION_BLOCK" => Some("END_FUNCTION_BLOCK"),
        "INTERFACE" => Some("END_INTERFACE"),
        _ => None,
    }
}

/// `xml` with every character outside `keep` a space (line breaks kept), and each word of
/// `words` (sorted by place) written at its place over those spaces; a word longer than the
/// spaces left on its line pushes the rest of the line, which holds XML only. The characters
/// of `joins` (sorted) are left out, and as many spaces written before the next line break.
fn blank_outside(
    xml: &str,
    keep: &[Range<usize>],
    joins: &[Range<usize>],
    words: &[(usize, String)],
) -> String {
    let mut out = String::with_capacity(xml.len() + 64);
    let mut kept = keep.iter().peekable();
    let mut joins = joins.iter().peekable();
    let mut words = words.iter().peekable();
    let mut covered = 0usize; // spaces still covered by the last word written
    let mut owed = 0usize; // spaces left out by joins, written at the end of the line
    for (i, ch) in xml.char_indices() {
        while kept.peek().is_some_and(|r| r.end <= i) {
            kept.next();
        }
        while joins.peek().is_some_and(|r| r.end <= i) {
            joins.next();
        }
        if joins.peek().is_some_and(|r| r.contains(&i)) {
            owed += 1;
            continue;
        }
        if ch == '\n' || ch == '\r' {
            out.extend(std::iter::repeat_n(' ', owed));
            owed = 0;
        }
        while let Some((_, word)) = words.next_if(|(at, _)| *at <= i) {
            if covered > 0 {
                out.push(' ');
            }
            out.push_str(word);
            covered += word.chars().count() + usize::from(covered > 0);
        }
        let inside = kept.peek().is_some_and(|r| r.contains(&i));
        if inside || ch == '\n' || ch == '\r' {
            out.push(ch);
            covered = 0;
        } else if covered > 0 {
            covered -= 1;
        } else {
            out.push(' ');
        }
    }
    for (_, word) in words {
        out.push('\n');
        out.push_str(word);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    const FB: &str = "\u{feff}<?xml version=\"1.0\" encoding=\"utf-8\"?>
<TcPlcObject Version=\"1.1.0.1\">
  <POU Name=\"Count\" Id=\"{1}\" SpecialFunc=\"None\">
    <Declaration><![CDATA[FUNCTION_BLOCK Count
VAR_OUTPUT n : INT; END_VAR]]></Declaration>
    <Implementation>
      <ST><![CDATA[n := n + 1;
IF n > 10 THEN n := 0; END_IF]]></ST>
    </Implementation>
    <LineIds Name=\"Count\">
      <LineId Id=\"3\" Count=\"1\" />
    </LineIds>
  </POU>
</TcPlcObject>";

    #[test]
    fn a_cdata_end_split_over_two_sections_is_read_as_one_text() {
        // TwinCAT's form of the ST `s := ']]>'; n := 1;` (OSCAT NETWORK's XML_READER)
        let text = "<TcPlcObject>\n  <POU Name=\"P\"><Declaration><![CDATA[PROGRAM P\nVAR s : STRING; n : INT; END_VAR]]></Declaration>\n    <Implementation>\n      <ST><![CDATA[s := ']]]]><![CDATA[>'; n := 1;\nn := 2;]]></ST>\n    </Implementation>\n  </POU>\n</TcPlcObject>";
        let st = st_text(text).unwrap();
        let lines: Vec<&str> = st.lines().collect();
        assert_eq!(lines.len(), text.lines().count(), "{st}");
        // the join is left out, and written as spaces at the end of its line
        let body = format!("{}s := ']]>'; n := 1;{}", " ".repeat(19), " ".repeat(12));
        assert_eq!(lines[4], body);
        assert_eq!(lines[4].len(), text.lines().nth(4).unwrap().len());
        // the next line keeps its columns
        assert_eq!(lines[5].trim_end(), "n := 2;");
    }

    #[test]
    fn sections_apart_are_not_joined() {
        let text = "<TcPlcObject><POU Name=\"P\"><Declaration><![CDATA[PROGRAM P]]></Declaration><Implementation><ST><![CDATA[a := ']]'; ]]><![CDATA[b := 1;]]> <![CDATA[c := 2;]]></ST></Implementation></POU></TcPlcObject>";
        let st = st_text(text).unwrap();
        // adjacent sections join (`']]'; ` then `b := 1;`), a blank between two stays a blank
        let joined = format!("a := ']]'; b := 1;{}c := 2;", " ".repeat("]]> <![CDATA[".len()));
        assert!(st.contains(&joined), "{st}");
    }

    #[test]
    fn a_pou_keeps_its_lines_and_columns_and_gets_its_end() {
        let st = st_text(FB).unwrap();
        let lines: Vec<&str> = st.lines().collect();
        assert_eq!(lines.len(), FB.lines().count());
        assert_eq!(lines[3].trim_end(), format!("{}FUNCTION_BLOCK Count", " ".repeat(26)));
        assert_eq!(lines[4].trim_end(), "VAR_OUTPUT n : INT; END_VAR");
        assert_eq!(lines[6].trim_end(), format!("{}n := n + 1;", " ".repeat(19)));
        assert_eq!(lines[7].trim_end(), "IF n > 10 THEN n := 0; END_IF");
        assert_eq!(lines[8].trim(), "END_FUNCTION_BLOCK");
        assert!(lines[9..].iter().all(|l| l.trim().is_empty()), "{lines:?}");
    }

    #[test]
    fn an_action_is_written_over_its_tags() {
        let text = "<TcPlcObject>\n  <POU Name=\"M\">\n    <Declaration><![CDATA[FUNCTION_BLOCK M\nVAR n : INT; END_VAR]]></Declaration>\n    <Implementation>\n      <ST><![CDATA[Reset();]]></ST>\n    </Implementation>\n    <Action Name=\"Reset\" Id=\"{9}\">\n      <Implementation>\n        <ST><![CDATA[n := 0;]]></ST>\n      </Implementation>\n    </Action>\n  </POU>\n</TcPlcObject>";
        let st = st_text(text).unwrap();
        let lines: Vec<&str> = st.lines().map(str::trim).collect();
        assert_eq!(
            lines,
            [
                "",
                "",
                "FUNCTION_BLOCK M",
                "VAR n : INT; END_VAR",
                "",
                "Reset();",
                "",
                "ACTION Reset:",
                "",
                "n := 0;",
                "",
                "END_ACTION",
                "END_FUNCTION_BLOCK",
                ""
            ]
        );
        // the body keeps its column: `<ST><![CDATA[` ends at column 21
        assert_eq!(st.lines().nth(9).unwrap().find('n'), Some(21));
    }

    #[test]
    fn types_and_globals_are_their_declaration() {
        let dut = "<TcPlcObject><DUT Name=\"P\"><Declaration><![CDATA[TYPE P : STRUCT x : INT; END_STRUCT\nEND_TYPE]]></Declaration></DUT></TcPlcObject>";
        let st = st_text(dut).unwrap();
        assert_eq!(st.trim(), "TYPE P : STRUCT x : INT; END_STRUCT\nEND_TYPE");
        let gvl = "<TcPlcObject>\n<GVL Name=\"G\"><Declaration><![CDATA[{attribute 'qualified_only'}\nVAR_GLOBAL g : INT; END_VAR\n]]></Declaration></GVL></TcPlcObject>";
        let st = st_text(gvl).unwrap();
        assert_eq!(st.lines().nth(2), Some("VAR_GLOBAL g : INT; END_VAR"));
    }

    #[test]
    fn a_gvl_is_named_by_its_name_attribute() {
        let gvl = "<TcPlcObject>\n<GVL Name=\"GVL_Param\"><Declaration><![CDATA[VAR_GLOBAL g : INT; END_VAR]]></Declaration></GVL></TcPlcObject>";
        assert_eq!(gvl_name(gvl).as_deref(), Some("GVL_Param"));
        let dut = "<TcPlcObject><DUT Name=\"P\"><Declaration><![CDATA[TYPE P : INT; END_TYPE]]></Declaration></DUT></TcPlcObject>";
        assert_eq!(gvl_name(dut), None);
    }

    #[test]
    fn what_is_not_read_is_refused_at_its_place() {
        let bad = "<TcPlcObject>\n  <POU Name=\"X\">\n";
        let e = st_text(bad).unwrap_err();
        assert!(e.message.starts_with("not valid XML"), "{e:?}");
        let fbd = "<TcPlcObject>\n  <POU Name=\"X\"><Declaration><![CDATA[PROGRAM X]]></Declaration>\n<Implementation><FBD/></Implementation></POU></TcPlcObject>";
        let e = st_text(fbd).unwrap_err();
        assert_eq!(e.span, Span { line: 3, col: 17 });
        assert!(e.message.contains("`<FBD>` body is graphical"), "{e:?}");
        let other = "<Project/>";
        assert!(st_text(other).unwrap_err().message.contains("`<TcPlcObject>` expected"));
        let nameless = "<TcPlcObject><POU><Declaration><![CDATA[TYPE X : INT; END_TYPE]]></Declaration></POU></TcPlcObject>";
        assert!(st_text(nameless).unwrap_err().message.contains("does not start with PROGRAM"));
    }

    #[test]
    fn a_pou_whose_last_section_ends_the_file_gets_its_end_on_a_new_line() {
        let text = "<TcPlcObject><POU><Declaration><![CDATA[PROGRAM P]]></Declaration><Implementation><ST><![CDATA[x := 1;]]></ST></Implementation></POU></TcPlcObject>";
        let st = st_text(text).unwrap();
        assert_eq!(st.lines().nth(1), Some("END_PROGRAM"));
        assert!(st.lines().next().unwrap().contains("PROGRAM P"));
    }

    #[test]
    fn methods_properties_and_interfaces_are_written_over_their_tags() {
        let text = "<TcPlcObject>\n  <POU Name=\"M\">\n    <Declaration><![CDATA[FUNCTION_BLOCK M IMPLEMENTS I\nVAR n : INT; END_VAR]]></Declaration>\n    <Implementation>\n      <ST><![CDATA[n := Up(1);]]></ST>\n    </Implementation>\n    <Method Name=\"Up\" Id=\"{9}\">\n      <Declaration><![CDATA[METHOD Up : INT\nVAR_INPUT k : INT; END_VAR]]></Declaration>\n      <Implementation>\n        <ST><![CDATA[Up := n + k;]]></ST>\n      </Implementation>\n    </Method>\n    <Property Name=\"P\" Id=\"{8}\">\n      <Declaration><![CDATA[PROPERTY P : INT]]></Declaration>\n      <Get Name=\"Get\" Id=\"{7}\">\n        <Declaration><![CDATA[VAR\nEND_VAR]]></Declaration>\n        <Implementation>\n          <ST><![CDATA[P := n;]]></ST>\n        </Implementation>\n      </Get>\n    </Property>\n  </POU>\n</TcPlcObject>";
        let st = st_text(text).unwrap();
        let lines: Vec<&str> = st.lines().map(str::trim).filter(|l| !l.is_empty()).collect();
        assert_eq!(
            lines,
            [
                "FUNCTION_BLOCK M IMPLEMENTS I",
                "VAR n : INT; END_VAR",
                "n := Up(1);",
                "METHOD Up : INT",
                "VAR_INPUT k : INT; END_VAR",
                "Up := n + k;",
                "END_METHOD",
                "PROPERTY P : INT",
                "GET",
                "VAR",
                "END_VAR",
                "P := n;",
                "END_GET",
                "END_PROPERTY",
                "END_FUNCTION_BLOCK",
            ]
        );
        let itf = "<TcPlcObject>\n  <Itf Name=\"I\">\n    <Declaration><![CDATA[INTERFACE I EXTENDS __System.IQueryInterface]]></Declaration>\n    <Method Name=\"Up\">\n      <Declaration><![CDATA[METHOD Up : INT\nVAR_INPUT k : INT; END_VAR]]></Declaration>\n    </Method>\n  </Itf>\n</TcPlcObject>";
        let st = st_text(itf).unwrap();
        let lines: Vec<&str> = st.lines().map(str::trim).filter(|l| !l.is_empty()).collect();
        assert_eq!(
            lines,
            [
                "INTERFACE I EXTENDS __System.IQueryInterface",
                "METHOD Up : INT",
                "VAR_INPUT k : INT; END_VAR",
                "END_METHOD",
                "END_INTERFACE"
            ]
        );
    }
}
