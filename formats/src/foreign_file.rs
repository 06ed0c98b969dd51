//! What the readers of other tools' files share: the error that names the file, and the few XML elements,
//! texts and attributes they need (OpenCV's FileStorage XML and Metashape's files are read directly: the handful of
//! tags needed do not call for an XML crate).

/// Another tool's file that cannot be used; the message names the file and what is wrong.
#[derive(Debug, thiserror::Error)]
#[error("{path}: {message}")]
pub struct ForeignFileError {
    /// The file.
    pub path: std::path::PathBuf,
    /// What is wrong.
    pub message: String,
}

/// Every `<tag …>…</tag>` or `<tag …/>` element of `text` in order, as (attributes, body); elements of one name do
/// not nest in the files read here.
pub(crate) fn xml_elements<'a>(text: &'a str, tag: &str) -> Vec<(&'a str, &'a str)> {
    let mut out = Vec::new();
    let (open, close) = (format!("<{tag}"), format!("</{tag}>"));
    let mut from = 0;
    while let Some(at) = text.get(from..).and_then(|t| t.find(&open)).map(|k| from + k) {
        let after = at + open.len();
        let Some(end) = text.get(after..).and_then(|t| t.find('>')).map(|k| after + k) else {
            break;
        };
        from = end + 1;
        if !text[after..].starts_with(['>', '/', ' ', '\t', '\n', '\r']) {
            continue;
        }
        let attributes = text[after..end].trim_end_matches('/');
        if text[..end].ends_with('/') {
            out.push((attributes, ""));
            continue;
        }
        let Some(stop) = text.get(from..).and_then(|t| t.find(&close)).map(|k| from + k) else {
            break;
        };
        out.push((attributes, &text[from..stop]));
        from = stop + close.len();
    }
    out
}

/// The value of `name="…"` in an element's attributes.
pub(crate) fn xml_attribute<'a>(attributes: &'a str, name: &str) -> Option<&'a str> {
    let at = attributes.find(&format!(" {name}=\""))? + name.len() + 3;
    let rest = &attributes[at..];
    Some(&rest[..rest.find('"')?])
}

/// The text between `<tag …>` and `</tag>` (the first such element).
pub(crate) fn xml_text<'a>(text: &'a str, tag: &str) -> Option<&'a str> {
    let mut from = 0;
    loop {
        let at = from + text.get(from..)?.find(&format!("<{tag}"))?;
        let after = at + 1 + tag.len();
        let rest = text.get(after..)?;
        if rest.starts_with(['>', ' ', '\t', '\n', '\r']) {
            let open_end = after + rest.find('>')? + 1;
            let close = open_end + text.get(open_end..)?.find(&format!("</{tag}>"))?;
            return text.get(open_end..close);
        }
        from = after;
    }
}
