//! [`SlotPixels`]: the image pixel of each camera-sample slot of the batch in flight,
//! listed, or named by the 4x4 blocks the slots were made for.
//!
//! Why: a 1-sample frame of whole 4x4 blocks (the bunny at 1024x1024) wrote each
//! camera ray's pixel index into a list (8 bytes a ray, a sixth of what the camera
//! stage writes per ray, with the ray, its accumulator and its place in the tile),
//! and its shading, Lambert under point lights, never reads it. A block's sixteen
//! indices are now made when a slot's pixel is asked for, from the block.

use super::camera_packets::block_pixel_indices;

/// Slots `0..listed.len()` have their pixel listed; the slots after them, sixteen a
/// block in order, are the pixels of `blocks` (an image `width` wide), in the lane
/// order of [`block_pixel_indices`].
#[derive(Default)]
pub(crate) struct SlotPixels {
    listed: Vec<u64>,
    blocks: Vec<(u32, u32)>,
    width: u32,
}

impl SlotPixels {
    /// The pixel of `slot` (a slot below [`Self::len`]).
    #[inline]
    pub fn get(&self, slot: u32) -> u64 {
        let s = slot as usize;
        match self.listed.get(s) {
            Some(&p) => p,
            None => {
                let k = s - self.listed.len();
                block_pixel_indices(self.blocks[k / 16], self.width)[k % 16]
            }
        }
    }

    /// Slots with a pixel.
    pub fn len(&self) -> usize {
        self.listed.len() + 16 * self.blocks.len()
    }

    pub fn clear(&mut self) {
        self.listed.clear();
        self.blocks.clear();
    }

    /// Gives the next `16 * blocks.len()` slots the pixels of `blocks` in an image
    /// `width` wide, block after block.
    pub fn push_blocks(&mut self, blocks: &[(u32, u32)], width: u32) {
        if !self.blocks.is_empty() && self.width != width {
            self.materialize();
        }
        self.width = width;
        self.blocks.extend_from_slice(blocks);
    }

    /// The list, for the next slots' pixels to be appended to it (after every block's
    /// pixels are listed).
    pub fn listed(&mut self) -> &mut Vec<u64> {
        self.materialize();
        &mut self.listed
    }

    fn materialize(&mut self) {
        for &b in &self.blocks {
            self.listed
                .extend_from_slice(&block_pixel_indices(b, self.width));
        }
        self.blocks.clear();
    }
}

impl From<Vec<u64>> for SlotPixels {
    fn from(listed: Vec<u64>) -> Self {
        SlotPixels {
            listed,
            ..Default::default()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Lists, blocks, lists after blocks, blocks of another width: every slot's pixel
    /// is the one a plain list of the same appends holds, and so is the length.
    #[test]
    fn block_slots_are_the_listed_pixels() {
        let mut got = SlotPixels::default();
        let mut want: Vec<u64> = Vec::new();
        let blocks = |n: u32, at: u32| -> Vec<(u32, u32)> {
            (0..n).map(|i| (4 * (i + at), 4 * (i % 3))).collect()
        };
        let check = |got: &SlotPixels, want: &[u64]| {
            assert_eq!(got.len(), want.len());
            for (s, &p) in want.iter().enumerate() {
                assert_eq!(got.get(s as u32), p, "slot {s}");
            }
        };
        let steps: [(&str, u32, u32); 7] = [
            ("blocks", 3, 640),
            ("list", 5, 0),
            ("blocks", 2, 640),
            ("blocks", 4, 640),
            ("blocks", 1, 1024),
            ("list", 17, 0),
            ("blocks", 2, 97),
        ];
        for (i, &(kind, n, width)) in steps.iter().enumerate() {
            if kind == "list" {
                let more: Vec<u64> = (0..n as u64).map(|p| 1000 * i as u64 + p).collect();
                got.listed().extend_from_slice(&more);
                want.extend_from_slice(&more);
            } else {
                let b = blocks(n, i as u32);
                got.push_blocks(&b, width);
                for &bk in &b {
                    let (bx, by) = (bk.0 as u64, bk.1 as u64);
                    want.extend((0..16u64).map(|l| (by + l / 4) * width as u64 + bx + l % 4));
                }
            }
            check(&got, &want);
        }
        got.clear();
        check(&got, &[]);
    }
}
