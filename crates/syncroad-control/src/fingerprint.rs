//! The fingerprint of what a run reads: FNV-1a (64 bits) as 16 hex digits, over a scenario as
//! written and the files it names (the user's controller source), so that two runs share a
//! hash only when they read the same inputs. Not a cryptographic hash: it tells experiments
//! apart, it does not defend against forgery.

/// FNV-1a of `bytes`, as 16 hex digits.
pub fn fnv1a_hex(bytes: impl AsRef<[u8]>) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in bytes.as_ref() {
        h ^= u64::from(*b);
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    format!("{h:016x}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_published_fnv1a_test_vectors() {
        // From the FNV reference (Fowler, Noll, Vo): the offset basis, "a" and "foobar".
        assert_eq!(fnv1a_hex(""), "cbf29ce484222325");
        assert_eq!(fnv1a_hex("a"), "af63dc4c8601ec8c");
        assert_eq!(fnv1a_hex("foobar"), "85944171f73967e8");
    }
}
