//! A small element tree of the XML part of a VTK XML file, built with quick-xml. Text is
//! borrowed from the file. Parsing can stop at an element (`AppendedData`) whose content is
//! raw binary and therefore not XML.

use quick_xml::events::{BytesStart, Event};
use quick_xml::{Reader, XmlVersion};
use std::borrow::Cow;

#[derive(Debug)]
pub(crate) struct Node<'a> {
    pub name: String,
    pub attrs: Vec<(String, String)>,
    /// The element's own text pieces (its children's text is theirs).
    pub text: Vec<Cow<'a, [u8]>>,
    pub children: Vec<Node<'a>>,
}

impl<'a> Node<'a> {
    fn new(e: &BytesStart) -> Result<Node<'a>, String> {
        let name = String::from_utf8_lossy(e.name().as_ref()).into_owned();
        let mut attrs = Vec::new();
        for a in e.attributes() {
            let a = a.map_err(|err| format!("<{name}>: bad attribute: {err}"))?;
            let key = String::from_utf8_lossy(a.key.as_ref()).into_owned();
            let value = a
                .normalized_value(XmlVersion::Implicit1_0)
                .map_err(|err| format!("<{name}>: bad value of attribute {key}: {err}"))?
                .into_owned();
            attrs.push((key, value));
        }
        Ok(Node { name, attrs, text: Vec::new(), children: Vec::new() })
    }

    pub fn attr(&self, key: &str) -> Option<&str> {
        self.attrs.iter().find(|(k, _)| k == key).map(|(_, v)| v.as_str())
    }

    pub fn child(&self, name: &str) -> Option<&Node<'a>> {
        self.children.iter().find(|c| c.name == name)
    }

    pub fn children_named<'s>(&'s self, name: &'s str) -> impl Iterator<Item = &'s Node<'a>> + 's {
        self.children.iter().filter(move |c| c.name == name)
    }

    /// The element's text as one slice (a copy only when it came in several pieces).
    pub fn text(&self) -> Cow<'_, [u8]> {
        match self.text.as_slice() {
            [] => Cow::Borrowed(&[]),
            [one] => Cow::Borrowed(one),
            many => Cow::Owned(many.concat()),
        }
    }
}

/// The parsed document: its root element and, if parsing stopped at `stop_at`, that
/// element (attributes only) and the byte position just after its start tag.
#[derive(Debug)]
pub(crate) struct Document<'a> {
    pub root: Node<'a>,
    pub stopped_at: Option<(Node<'a>, usize)>,
}

/// Parses `bytes` (a leading UTF-8 byte-order mark is skipped; positions count it).
pub(crate) fn parse<'a>(bytes: &'a [u8], stop_at: &str) -> Result<Document<'a>, String> {
    let text = crate::strip_bom(bytes);
    let bom = bytes.len() - text.len();
    let mut reader = Reader::from_reader(text);
    reader.config_mut().check_end_names = true;
    // The bottom of the stack holds the document's top-level elements.
    let mut stack: Vec<Node<'a>> = vec![Node { name: String::new(), attrs: vec![], text: vec![], children: vec![] }];
    let mut stopped_at = None;
    loop {
        let ev =
            reader.read_event().map_err(|e| format!("malformed XML near byte {}: {e}", reader.error_position()))?;
        match ev {
            Event::Start(e) if e.name().as_ref() == stop_at.as_bytes() => {
                stopped_at = Some((Node::new(&e)?, bom + reader.buffer_position() as usize));
                break;
            }
            Event::Start(e) => stack.push(Node::new(&e)?),
            Event::Empty(e) => {
                let node = Node::new(&e)?;
                stack.last_mut().unwrap().children.push(node);
            }
            Event::End(_) => {
                if stack.len() < 2 {
                    return Err(format!(
                        "malformed XML near byte {}: closing tag without opening tag",
                        reader.buffer_position()
                    ));
                }
                let node = stack.pop().unwrap();
                stack.last_mut().unwrap().children.push(node);
            }
            Event::Text(t) => stack.last_mut().unwrap().text.push(t.into_inner()),
            Event::CData(t) => stack.last_mut().unwrap().text.push(t.into_inner()),
            Event::Eof => break,
            _ => {}
        }
    }
    if stopped_at.is_none() && stack.len() > 1 {
        return Err(format!("the file ends inside <{}>: truncated?", stack.last().unwrap().name));
    }
    // Close what the stop left open.
    while stack.len() > 1 {
        let node = stack.pop().unwrap();
        stack.last_mut().unwrap().children.push(node);
    }
    let mut doc = stack.pop().unwrap();
    if doc.children.len() != 1 {
        return Err(format!("expected one root element, found {}", doc.children.len()));
    }
    Ok(Document { root: doc.children.pop().unwrap(), stopped_at })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tree_and_stop() {
        let src = b"<?xml version=\"1.0\"?>\n<A x=\"1 &amp; 2\"><B/><C>12 <!-- c --> 34</C><D>data<E/></D>\
                    <Stop k=\"v\">\n _\x00\x01<<garbage";
        let doc = parse(src, "Stop").unwrap();
        assert_eq!(doc.root.name, "A");
        assert_eq!(doc.root.attr("x"), Some("1 & 2"));
        assert_eq!(doc.root.children.iter().map(|c| c.name.as_str()).collect::<Vec<_>>(), ["B", "C", "D"]);
        assert_eq!(&*doc.root.child("C").unwrap().text(), b"12  34");
        assert_eq!(&*doc.root.child("D").unwrap().text(), b"data");
        let (stop, pos) = doc.stopped_at.unwrap();
        assert_eq!(stop.attr("k"), Some("v"));
        assert_eq!(&src[pos..pos + 3], b"\n _");
    }

    #[test]
    fn errors() {
        assert!(parse(b"<A><B></A>", "X").is_err());
        assert!(parse(b"<A><B></B>", "X").unwrap_err().contains("truncated"));
        assert!(parse(b"<A/><B/>", "X").is_err());
        assert!(parse(b"", "X").is_err());
        assert!(parse(b"<A x=1/>", "X").is_err());
    }
}
