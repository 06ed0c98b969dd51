//! Two-part payloads: a byte payload holding `[A]` followed by `[B]`, each part starting 8-byte aligned.
//!
//! The header of such a message states the element counts; the byte offset of the second part is
//! `align8(count_a * size_of::<A>())`. iceoryx2 places a payload 8-byte aligned, so both parts are aligned for
//! any element type whose alignment is at most 8.

use iceoryx2::prelude::ZeroCopySend;

/// Rounds up to a multiple of 8.
pub const fn align8(n: usize) -> usize {
    (n + 7) & !7
}

/// Byte length of a two-part payload.
pub fn two_part_len<A, B>(count_a: usize, count_b: usize) -> usize {
    align8(count_a * size_of::<A>()) + count_b * size_of::<B>()
}

/// Why a two-part payload cannot be read.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PartsError {
    /// Bytes the header's counts need.
    pub need: usize,
    /// Bytes the payload has.
    pub have: usize,
}

impl std::fmt::Display for PartsError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "payload has {} bytes but its header's counts need {} (or it is misaligned)",
            self.have, self.need
        )
    }
}
impl std::error::Error for PartsError {}

/// Reads the two parts of `bytes`.
///
/// # Errors
/// When the payload is shorter than the counts need or not 8-byte aligned.
pub fn split<A: ZeroCopySend + Copy, B: ZeroCopySend + Copy>(
    bytes: &[u8],
    count_a: usize,
    count_b: usize,
) -> Result<(&[A], &[B]), PartsError> {
    let need = two_part_len::<A, B>(count_a, count_b);
    if bytes.len() < need || !(bytes.as_ptr() as usize).is_multiple_of(8) || align_of::<A>() > 8 || align_of::<B>() > 8 {
        return Err(PartsError { need, have: bytes.len() });
    }
    let off_b = align8(count_a * size_of::<A>());
    // SAFETY: length and 8-byte alignment checked above; A and B are plain-old-data message elements
    // (ZeroCopySend + Copy, repr(C) without pointers), so every bit pattern the publisher wrote is a value.
    unsafe {
        Ok((
            std::slice::from_raw_parts(bytes.as_ptr().cast::<A>(), count_a),
            std::slice::from_raw_parts(bytes.as_ptr().add(off_b).cast::<B>(), count_b),
        ))
    }
}

/// Writes `a` then `b` into `out` (which must be [`two_part_len`] long and 8-byte aligned).
///
/// # Panics
/// When `out` has the wrong length or alignment: a programming error in the caller's loan size.
pub fn write<A: ZeroCopySend + Copy, B: ZeroCopySend + Copy>(out: &mut [u8], a: &[A], b: &[B]) {
    let need = two_part_len::<A, B>(a.len(), b.len());
    assert!(
        out.len() == need && (out.as_ptr() as usize).is_multiple_of(8),
        "two-part payload of {} bytes, need {need}",
        out.len()
    );
    out.fill(0);
    let off_b = align8(std::mem::size_of_val(a));
    // SAFETY: sizes checked above; the regions do not overlap and A, B are plain-old-data.
    unsafe {
        std::ptr::copy_nonoverlapping(a.as_ptr().cast::<u8>(), out.as_mut_ptr(), std::mem::size_of_val(a));
        std::ptr::copy_nonoverlapping(b.as_ptr().cast::<u8>(), out.as_mut_ptr().add(off_b), std::mem::size_of_val(b));
    }
}
