//! A cheap, stable checksum, the same on every machine and build (unlike `std`'s `DefaultHasher`).

/// FNV-1a offset basis: the checksum of no bytes.
pub const FNV1A64_START: u64 = 0xcbf2_9ce4_8422_2325;

/// 64-bit FNV-1a of `bytes`: a cheap, stable checksum for comparing frames across runs and tools.
pub fn fnv1a64(bytes: &[u8]) -> u64 {
    fnv1a64_extend(FNV1A64_START, bytes)
}

/// Continues a checksum `h` over more bytes, so that data in pieces is hashed without gathering it first.
pub fn fnv1a64_extend(h: u64, bytes: &[u8]) -> u64 {
    bytes.iter().fold(h, |h, &b| (h ^ b as u64).wrapping_mul(0x0100_0000_01b3))
}

#[cfg(test)]
mod tests {
    #[test]
    fn fnv_matches_the_reference_vectors() {
        assert_eq!(super::fnv1a64(b""), 0xcbf29ce484222325);
        assert_eq!(super::fnv1a64(b"a"), 0xaf63dc4c8601ec8c);
        assert_eq!(super::fnv1a64_extend(super::fnv1a64(b"ab"), b"c"), super::fnv1a64(b"abc"));
    }
}
