//! Natural file-name order: `IMG_2` before `IMG_10`.
use std::cmp::Ordering;

/// Compares two names treating runs of ASCII digits as numbers (then by length, so `01` sorts after `1`), and
/// other characters case-insensitively, falling back to the exact bytes so the order is total.
pub fn natural_cmp(a: &str, b: &str) -> Ordering {
    let (mut x, mut y) = (a.as_bytes(), b.as_bytes());
    while let (Some(&ca), Some(&cb)) = (x.first(), y.first()) {
        if ca.is_ascii_digit() && cb.is_ascii_digit() {
            let na = x.iter().take_while(|c| c.is_ascii_digit()).count();
            let nb = y.iter().take_while(|c| c.is_ascii_digit()).count();
            let (da, db) = (&x[..na], &y[..nb]);
            let ta = trim_zeros(da);
            let tb = trim_zeros(db);
            let ord = ta.len().cmp(&tb.len()).then_with(|| ta.cmp(tb)).then_with(|| na.cmp(&nb));
            if ord != Ordering::Equal {
                return ord;
            }
            x = &x[na..];
            y = &y[nb..];
        } else {
            let ord = ca.to_ascii_lowercase().cmp(&cb.to_ascii_lowercase());
            if ord != Ordering::Equal {
                return ord;
            }
            x = &x[1..];
            y = &y[1..];
        }
    }
    x.len().cmp(&y.len()).then_with(|| a.cmp(b))
}

fn trim_zeros(d: &[u8]) -> &[u8] {
    let z = d.iter().take_while(|&&c| c == b'0').count();
    &d[z..]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_sort_by_value_and_letters_ignore_case() {
        let mut v = vec![
            "IMG_10.jpg",
            "img_2.JPG",
            "IMG_1.jpg",
            "IMG_02.jpg",
            "a",
            "IMG_100.png",
            "IMG_9.tif",
        ];
        v.sort_by(|a, b| natural_cmp(a, b));
        assert_eq!(
            v,
            vec![
                "a",
                "IMG_1.jpg",
                "img_2.JPG",
                "IMG_02.jpg",
                "IMG_9.tif",
                "IMG_10.jpg",
                "IMG_100.png"
            ]
        );
    }
}
