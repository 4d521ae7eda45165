//! What a texture lookup does outside `[0, 1]`: the texel index a lookup asks for
//! (any integer) is folded back into the image.

/// Texel addressing outside the image.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum WrapMode {
    /// Tile the image (`u = 1.25` reads what `u = 0.25` reads).
    #[default]
    Repeat,
    /// Repeat the edge texels (`u = 1.25` reads the last column).
    Clamp,
    /// Tile with every other copy flipped (`u = 1.25` reads what `u = 0.75` reads).
    Mirror,
}

impl WrapMode {
    /// Parses `repeat`, `clamp` or `mirror`.
    pub fn parse(s: &str) -> Option<WrapMode> {
        match s {
            "repeat" => Some(WrapMode::Repeat),
            "clamp" => Some(WrapMode::Clamp),
            "mirror" => Some(WrapMode::Mirror),
            _ => None,
        }
    }

    /// The texel index in `0..n` that index `i` (any integer) reads. `n` must be > 0.
    #[inline]
    pub fn texel(self, i: i64, n: u32) -> u32 {
        let n = n as i64;
        let k = match self {
            WrapMode::Repeat => i.rem_euclid(n),
            WrapMode::Clamp => i.clamp(0, n - 1),
            WrapMode::Mirror => {
                let k = i.rem_euclid(2 * n);
                if k < n { k } else { 2 * n - 1 - k }
            }
        };
        k as u32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_mode_folds_indices_as_documented() {
        let n = 4;
        let idx = |m: WrapMode| (-5..9).map(|i| m.texel(i, n)).collect::<Vec<_>>();
        // i = -5 .. 8
        assert_eq!(
            idx(WrapMode::Repeat),
            [3, 0, 1, 2, 3, 0, 1, 2, 3, 0, 1, 2, 3, 0]
        );
        assert_eq!(
            idx(WrapMode::Clamp),
            [0, 0, 0, 0, 0, 0, 1, 2, 3, 3, 3, 3, 3, 3]
        );
        // period 8: 0 1 2 3 3 2 1 0
        assert_eq!(
            idx(WrapMode::Mirror),
            [3, 3, 2, 1, 0, 0, 1, 2, 3, 3, 2, 1, 0, 0]
        );
    }

    #[test]
    fn extreme_indices_stay_in_range() {
        for m in [WrapMode::Repeat, WrapMode::Clamp, WrapMode::Mirror] {
            for i in [i64::MIN / 4, -1, i64::MAX / 4] {
                assert!(m.texel(i, 3) < 3, "{m:?} {i}");
            }
        }
    }
}
