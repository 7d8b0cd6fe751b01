//! TwinCAT 3's PLC project files (`.plcproj`, MSBuild XML) read for the namespaces that qualify
//! the project's declarations (docs/ST.md, "Qualified names").
//!
//! TwinCAT learns a library's namespace from its project files, never from the sources: a
//! library project states its own (`<PropertyGroup><DefaultNamespace>TcUnit</DefaultNamespace>`),
//! and a project that uses libraries names each reference's
//! (`<ItemGroup><PlaceholderReference Include="TcUnit">…<Namespace>TcUnit</Namespace>`, or a
//! `<LibraryReference>`'s). [`namespaces`] reads those three places and nothing else of the
//! file: the compile items, options and build settings mean nothing to plcd. Which files are
//! read (those in `[st] library` folders, the one nearest a `[[program]]`'s TwinCAT file) is
//! the project loader's business (`crate::project`), as reading them is the caller's.

use std::fmt;

use crate::config::is_namespace;
use crate::st::ast::Span;
use crate::st::twincat::{parse_rooted, span_at, XmlError};

/// Which element of a `.plcproj` names a namespace.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Origin {
    /// `<PropertyGroup><DefaultNamespace>`: the project's own declarations' namespace.
    DefaultNamespace,
    /// `<ItemGroup><PlaceholderReference Include="…"><Namespace>`: a library the project uses,
    /// by its placeholder (the `Include`).
    PlaceholderReference(String),
    /// `<ItemGroup><LibraryReference Include="…"><Namespace>`: a library the project uses, by
    /// its name, version and vendor (`Base Interfaces,newest,System`).
    LibraryReference(String),
}

impl fmt::Display for Origin {
    /// As the file writes it: `<DefaultNamespace>`, `<PlaceholderReference Include="TcUnit">`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Origin::DefaultNamespace => write!(f, "<DefaultNamespace>"),
            Origin::PlaceholderReference(include) => {
                write!(f, "<PlaceholderReference Include=\"{include}\">")
            }
            Origin::LibraryReference(include) => {
                write!(f, "<LibraryReference Include=\"{include}\">")
            }
        }
    }
}

/// A namespace a `.plcproj` names: the name, where its text starts, and which element.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Namespace {
    pub name: String,
    pub span: Span,
    pub origin: Origin,
}

/// The namespaces a `.plcproj` names, in file order (a name may come twice). An element
/// without text (`<DefaultNamespace />`) names none, as does a reference without a
/// `<Namespace>`: TwinCAT keeps a library's own default in the library, which plcd does not
/// read. Errors, at their place in the file: XML that is not well formed (the one error then),
/// a root other than `<Project>`, and every namespace that is not a name (all of them).
pub fn namespaces(xml: &str) -> Result<Vec<Namespace>, Vec<XmlError>> {
    let doc = parse_rooted(xml, "Project", "a TwinCAT PLC project").map_err(|e| vec![e])?;
    let at = |pos: usize| span_at(&doc, pos);
    let root = doc.root_element();
    let mut found = Vec::new();
    for group in elements(root) {
        match group.tag_name().name() {
            "PropertyGroup" => {
                let named = elements(group).filter(|n| n.tag_name().name() == "DefaultNamespace");
                found.extend(named.map(|n| (n, Origin::DefaultNamespace)));
            }
            "ItemGroup" => {
                for reference in elements(group) {
                    let include = reference.attribute("Include").unwrap_or_default().to_string();
                    let origin = match reference.tag_name().name() {
                        "PlaceholderReference" => Origin::PlaceholderReference(include),
                        "LibraryReference" => Origin::LibraryReference(include),
                        _ => continue,
                    };
                    let named = elements(reference).filter(|n| n.tag_name().name() == "Namespace");
                    found.extend(named.map(|n| (n, origin.clone())));
                }
            }
            _ => {}
        }
    }
    let mut names = Vec::new();
    let mut errors = Vec::new();
    for (element, origin) in found {
        // the element's text, entities resolved; its place is its first character that is
        // not white space, in the file as written
        let text: String =
            element.children().filter(|n| n.is_text()).filter_map(|n| n.text()).collect();
        let name = text.trim();
        if name.is_empty() {
            continue;
        }
        let first_text = element.children().find(|n| n.is_text());
        let start = first_text.map_or(element.range().start, |n| n.range().start);
        let blank = xml[start..].len() - xml[start..].trim_start().len();
        let span = at(start + blank);
        if is_namespace(name) {
            names.push(Namespace { name: name.to_string(), span, origin });
        } else {
            let element = element.tag_name().name();
            let message = match &origin {
                Origin::DefaultNamespace => {
                    format!("the `<{element}>` `{name}` is not a name (letters, digits and `_`)")
                }
                _ => format!(
                    "the `<{element}>` `{name}` of `{origin}` is not a name (letters, digits and `_`)"
                ),
            };
            errors.push(XmlError { span, message });
        }
    }
    if errors.is_empty() {
        Ok(names)
    } else {
        Err(errors)
    }
}

/// The element children of `node`.
fn elements<'a, 'i>(
    node: roxmltree::Node<'a, 'i>,
) -> impl Iterator<Item = roxmltree::Node<'a, 'i>> {
    node.children().filter(|n| n.is_element())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The shape of TcUnit's verifier project (github.com/tcunit/TcUnit,
    /// `TcUnit-Verifier/TcUnitVerifier/TcUnitVerifier.plcproj`), abridged and written here.
    const APP: &str = r#"<?xml version="1.0" encoding="utf-8"?>
<Project DefaultTargets="Build" xmlns="http://schemas.microsoft.com/developer/msbuild/2003">
  <PropertyGroup>
    <Name>App</Name>
    <DefaultNamespace>App</DefaultNamespace>
  </PropertyGroup>
  <ItemGroup>
    <Compile Include="POUs\MAIN.TcPOU">
      <SubType>Code</SubType>
    </Compile>
  </ItemGroup>
  <ItemGroup>
    <PlaceholderReference Include="Tc2_Standard">
      <DefaultResolution>Tc2_Standard, * (Beckhoff Automation GmbH)</DefaultResolution>
      <Namespace>Tc2_Standard</Namespace>
    </PlaceholderReference>
    <PlaceholderReference Include="MyLib">
      <DefaultResolution>MyLib, * (plcd)</DefaultResolution>
      <Namespace> MyLib </Namespace>
      <Parameters>
        <Parameter ListName="PARAM" xmlns="">
          <Key>N</Key>
          <Value>4</Value>
        </Parameter>
      </Parameters>
    </PlaceholderReference>
  </ItemGroup>
  <ItemGroup>
    <LibraryReference Include="Base Interfaces,newest,System">
      <Namespace>IBaseLibrary</Namespace>
    </LibraryReference>
  </ItemGroup>
</Project>"#;

    fn named(found: &[Namespace]) -> Vec<(&str, u32, u32, String)> {
        found
            .iter()
            .map(|n| (n.name.as_str(), n.span.line, n.span.col, n.origin.to_string()))
            .collect()
    }

    #[test]
    fn the_default_namespace_and_each_references_are_read_where_written() {
        let found = namespaces(APP).unwrap();
        assert_eq!(
            named(&found),
            [
                ("App", 5, 23, "<DefaultNamespace>".to_string()),
                ("Tc2_Standard", 15, 18, "<PlaceholderReference Include=\"Tc2_Standard\">".into()),
                // trimmed, at its first letter
                ("MyLib", 19, 19, "<PlaceholderReference Include=\"MyLib\">".into()),
                (
                    "IBaseLibrary",
                    30,
                    18,
                    "<LibraryReference Include=\"Base Interfaces,newest,System\">".into()
                ),
            ]
        );
    }

    #[test]
    fn a_project_without_namespaces_names_none() {
        let empty = "<Project><PropertyGroup><Name>P</Name><DefaultNamespace/></PropertyGroup>\n<ItemGroup><PlaceholderReference Include=\"X\"><DefaultResolution>X, *</DefaultResolution></PlaceholderReference><Namespace>NotInAReference</Namespace></ItemGroup></Project>";
        assert_eq!(namespaces(empty).unwrap(), []);
        assert_eq!(namespaces("<Project/>").unwrap(), []);
        // elsewhere than the three places, a namespace element means nothing
        let elsewhere = "<Project><ProjectExtensions><DefaultNamespace>Q</DefaultNamespace></ProjectExtensions></Project>";
        assert_eq!(namespaces(elsewhere).unwrap(), []);
    }

    #[test]
    fn entities_are_resolved_and_a_name_twice_is_kept_twice() {
        let text = "<Project>\n<PropertyGroup><DefaultNamespace>A&#95;B</DefaultNamespace></PropertyGroup>\n<PropertyGroup Condition=\"'$(Configuration)' == 'Release'\"><DefaultNamespace>A_B</DefaultNamespace></PropertyGroup>\n</Project>";
        let found = namespaces(text).unwrap();
        assert_eq!(
            named(&found),
            [
                ("A_B", 2, 34, "<DefaultNamespace>".into()),
                ("A_B", 3, 78, "<DefaultNamespace>".into())
            ]
        );
    }

    #[test]
    fn xml_that_is_not_well_formed_is_one_error_at_its_place() {
        let errors = namespaces("<Project>\n  <PropertyGroup>\n</Project>").unwrap_err();
        assert_eq!(errors.len(), 1);
        assert_eq!((errors[0].span.line, errors[0].span.col), (3, 1));
        assert_eq!(
            errors[0].message,
            "not valid XML: expected 'PropertyGroup' tag, not 'Project' at 3:1"
        );
    }

    #[test]
    fn a_root_other_than_project_is_refused() {
        let errors = namespaces("<?xml version=\"1.0\"?>\n<TcPlcObject/>").unwrap_err();
        assert_eq!(errors.len(), 1);
        assert_eq!((errors[0].span.line, errors[0].span.col), (2, 1));
        assert_eq!(
            errors[0].message,
            "`<TcPlcObject>` is not a TwinCAT PLC project: `<Project>` expected"
        );
    }

    #[test]
    fn every_namespace_that_is_not_a_name_is_an_error_at_its_text() {
        let text = "<Project>\n<PropertyGroup><DefaultNamespace>My Lib</DefaultNamespace></PropertyGroup>\n<ItemGroup>\n  <PlaceholderReference Include=\"x\"><Namespace>\n    1st</Namespace></PlaceholderReference>\n  <LibraryReference Include=\"y\"><Namespace>$(Name)</Namespace></LibraryReference>\n  <PlaceholderReference Include=\"ok\"><Namespace>Fine</Namespace></PlaceholderReference>\n</ItemGroup>\n</Project>";
        let errors = namespaces(text).unwrap_err();
        let got: Vec<(u32, u32, &str)> =
            errors.iter().map(|e| (e.span.line, e.span.col, e.message.as_str())).collect();
        assert_eq!(
            got,
            [
                (2, 34, "the `<DefaultNamespace>` `My Lib` is not a name (letters, digits and `_`)"),
                (5, 5, "the `<Namespace>` `1st` of `<PlaceholderReference Include=\"x\">` is not a name (letters, digits and `_`)"),
                (6, 44, "the `<Namespace>` `$(Name)` of `<LibraryReference Include=\"y\">` is not a name (letters, digits and `_`)"),
            ]
        );
    }
}
