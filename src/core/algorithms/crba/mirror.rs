//! `H`'s upper triangle copied from its lower one by tiles, for the sizes where storing each
//! entry's mirror beside it is slow ([`Plan::mirror_by_tiles`](crate::plan::Plan::mirror_by_tiles)).
//!
//! The passes write each row of `H` down its column (`H[c, r]` for `c ≥ r`, contiguous in
//! column-major storage); the mirror `H[r, c]` of each entry steps `n` entries a store, and for
//! some `n` (multiples of 64 from 128 on the worst) those stores fall in a few sets of the L1
//! cache and miss, making CRBA on such chains several times slower. A tile reads eight
//! contiguous runs of the lower triangle and writes eight of the upper, a cache line each.

/// `H[r, c] = H[c, r]` for `r < c` up to the end of row `r`'s pattern (`subtree_end[r]`; entries
/// beyond are zero in both triangles), `h` being `n × n` column-major, by tiles of eight rows
/// and eight columns.
pub(super) fn mirror_lower(h: &mut [f64], n: usize, subtree_end: &[usize]) {
    const TILE: usize = 8;
    for r0 in (0..n).step_by(TILE) {
        let r1 = (r0 + TILE).min(n);
        let last = subtree_end[r0..r1].iter().copied().max().unwrap_or(r1);
        for c0 in (r0..last).step_by(TILE) {
            for c in c0..(c0 + TILE).min(last) {
                for r in r0..r1.min(c) {
                    h[c * n + r] = h[r * n + c];
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// On a branched pattern of 19 coordinates (three tiles of rows, subtrees ending inside and
    /// across tiles), the copy makes every entry in the pattern equal its mirror and leaves
    /// the zeros outside it alone.
    #[test]
    fn the_upper_triangle_is_the_mirror_of_the_lower() {
        let n = 19;
        // Coordinate 0 is the root; 1..10 a chain; 10..19 a second branch from 0.
        let subtree_end: Vec<usize> = (0..n)
            .map(|r| match r {
                0 => n,
                1..=9 => 10,
                _ => n,
            })
            .collect();
        let in_pattern = |r: usize, c: usize| c < subtree_end[r];
        let mut h = vec![0.0; n * n];
        for r in 0..n {
            for c in r..n {
                if in_pattern(r, c) {
                    h[r * n + c] = (1 + r * n + c) as f64; // H[c, r]
                }
            }
        }
        mirror_lower(&mut h, n, &subtree_end);
        for r in 0..n {
            for c in r..n {
                let (lower, upper) = (h[r * n + c], h[c * n + r]);
                assert_eq!(upper, lower, "H[{r}, {c}]");
                assert_eq!(lower != 0.0, in_pattern(r, c), "H[{c}, {r}]");
            }
        }
    }
}
