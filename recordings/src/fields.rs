//! A message's fields by name, from its schema (`lineflow_messages::schema`), as JSON: what `lineflow echo`
//! prints. The bytes are the in-memory form (the header struct and the payload as published), not CDR.
use lineflow_messages::schema::{Elem, FieldType, Layout, Payload, Scalar};
use lineflow_messages::MessageKind;
use serde_json::{json, Map, Value};

/// The header's fields and each payload sequence (its length and its first `max_elements` elements; raw bytes
/// only by their length) of a message of `kind`.
pub fn message_json(kind: MessageKind, header: &[u8], payload: &[u8], max_elements: usize) -> Value {
    let schema = kind.schema();
    let mut out = struct_json(schema.header, header);
    match schema.payload {
        Payload::Empty => {}
        Payload::One(part) => {
            out.insert(part.name.into(), sequence_json(part.elem, payload, None, max_elements));
        }
        Payload::Two { count, a, b } => {
            let n = out.get(count).and_then(Value::as_u64).unwrap_or(0) as usize;
            let a_bytes = (n * elem_size(a.elem)).min(payload.len());
            let b_start = a_bytes.next_multiple_of(8).min(payload.len());
            out.insert(a.name.into(), sequence_json(a.elem, &payload[..a_bytes], Some(n), max_elements));
            out.insert(b.name.into(), sequence_json(b.elem, &payload[b_start..], None, max_elements));
        }
    }
    Value::Object(out)
}

fn elem_size(elem: Elem) -> usize {
    match elem {
        Elem::Byte => 1,
        Elem::Struct(l) => l.size,
    }
}

fn sequence_json(elem: Elem, bytes: &[u8], count: Option<usize>, max_elements: usize) -> Value {
    match elem {
        Elem::Byte => json!({ "bytes": bytes.len() }),
        Elem::Struct(l) => {
            let n = count.unwrap_or(bytes.len() / l.size.max(1));
            let first: Vec<Value> = bytes
                .chunks_exact(l.size.max(1))
                .take(n.min(max_elements))
                .map(|e| Value::Object(struct_json(l, e)))
                .collect();
            json!({ "count": n, "first": first })
        }
    }
}

fn struct_json(layout: &Layout, bytes: &[u8]) -> Map<String, Value> {
    let mut out = Map::new();
    for f in layout.fields {
        // Reserved and padding fields say nothing.
        if f.name.starts_with("reserved") || f.name.starts_with("pad") {
            continue;
        }
        let Some(at) = bytes.get(f.offset..f.offset + f.ty.size()) else {
            continue;
        };
        let value = match f.ty {
            FieldType::Scalar(s) => scalar(s, at),
            FieldType::Array(s, n) => Value::Array((0..n).map(|i| scalar(s, &at[i * s.size()..])).collect()),
            FieldType::Text(_) => {
                let end = at.iter().position(|&c| c == 0).unwrap_or(at.len());
                Value::String(String::from_utf8_lossy(&at[..end]).into_owned())
            }
            FieldType::Struct(l) => Value::Object(struct_json(l, at)),
        };
        out.insert(f.name.into(), value);
    }
    out
}

fn scalar(s: Scalar, b: &[u8]) -> Value {
    let le = |n: usize| {
        let mut a = [0u8; 8];
        a[..n].copy_from_slice(&b[..n]);
        u64::from_le_bytes(a)
    };
    match s {
        Scalar::U8 => json!(b[0]),
        Scalar::U16 => json!(le(2) as u16),
        Scalar::U32 => json!(le(4) as u32),
        Scalar::U64 => json!(le(8)),
        Scalar::I32 => json!(le(4) as u32 as i32),
        Scalar::F32 => json!(f32::from_bits(le(4) as u32)),
        Scalar::F64 => json!(f64::from_bits(le(8))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use lineflow_messages::schema::bytes_of;
    use lineflow_messages::{Line3, Lines3DHeader, Stamp};

    #[test]
    fn a_header_and_its_elements_decode_by_name() {
        let header = Lines3DHeader {
            stamp: Stamp {
                frame: 7,
                ..Default::default()
            },
        };
        let line = Line3 {
            start_m: [1.0, 2.0, 3.0],
            end_m: [4.0, 5.5, 6.0],
            ..Default::default()
        };
        let payload: Vec<u8> = [line, line].iter().flat_map(|l| bytes_of(l).to_vec()).collect();
        let v = message_json(MessageKind::Lines3D, bytes_of(&header), &payload, 1);
        assert_eq!(v["stamp"]["frame"], 7);
        let lines = v.as_object().unwrap().values().find(|x| x.get("count").is_some()).unwrap();
        assert_eq!(lines["count"], 2);
        assert_eq!(lines["first"].as_array().unwrap().len(), 1);
        assert_eq!(lines["first"][0]["end_m"], json!([4.0, 5.5, 6.0]));
    }
}
