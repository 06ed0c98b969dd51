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

/// Every `<tag …>…</tag>` or `<tag …/>` element of `text` in order, as (attributes, body), found as they are
/// asked for; elements of one name do not nest in the files read here.
pub(crate) fn xml_elements<'a>(text: &'a str, tag: &str) -> impl Iterator<Item = (&'a str, &'a str)> {
    let (open, close) = (format!("<{tag}"), format!("</{tag}>"));
    let mut from = 0;
    std::iter::from_fn(move || loop {
        let at = from + text.get(from..)?.find(&open)?;
        let after = at + open.len();
        let end = after + text.get(after..)?.find('>')?;
        from = end + 1;
        if !text[after..].starts_with(['>', '/', ' ', '\t', '\n', '\r']) {
            continue;
        }
        let attributes = text[after..end].trim_end_matches('/');
        if text[..end].ends_with('/') {
            return Some((attributes, ""));
        }
        let stop = from + text.get(from..)?.find(&close)?;
        let body = &text[from..stop];
        from = stop + close.len();
        return Some((attributes, body));
    })
}

/// The value of `name="…"` in an element's attributes.
pub(crate) fn xml_attribute<'a>(attributes: &'a str, name: &str) -> Option<&'a str> {
    let at = attributes.find(&format!(" {name}=\""))? + name.len() + 3;
    let rest = &attributes[at..];
    Some(&rest[..rest.find('"')?])
}

/// The body of the first `<tag …>…</tag>` element.
pub(crate) fn xml_text<'a>(text: &'a str, tag: &str) -> Option<&'a str> {
    xml_elements(text, tag).next().map(|(_, body)| body)
}
