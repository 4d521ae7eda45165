//! The binned-SAH builder shared by the BVH2 and the N-wide BVHs (Wald 2007, "On fast
//! Construction of SAH-based Bounding Volume Hierarchies"), laid out for large meshes
//! the way Embree's builders are: each primitive is one 32-byte [`PrimRef`] (its box,
//! its index in a spare lane), and every level reads and writes these arrays in order
//! instead of gathering boxes and centroids through an index array.
//!
//! A node's references are partitioned out of place into a second array of the same
//! length, and the two arrays swap roles at each level (no copy back); left keeps the
//! input order, right reverses it. Nodes of at least [`PARALLEL_NODE`] primitives bin
//! in parallel chunks from the root on and, with more than one thread, partition in
//! parallel too (count per chunk, then scatter); their subtrees go to separate threads.
//! They choose their split from a sample of their references ([`SAMPLED_BINNING`]).
//! Leaves write their primitives' indices into the output order as they are made.
//!
//! Dead ends, measured at 1 thread on the procedural mesh (see README, "Build
//! scaling"): the previous builder gathered a 32-byte box and a 16-byte centroid
//! through an index array and copied each partition back from scratch; at 10^7
//! triangles it built at 0.65 Mtriangles/s, half its rate at 10^5.
//!
//! Dead end, 2026-11-24 (commit b43836f on branch `builder3`, reverted): the children
//! binned inside their parent's partition, one pass per level instead of two. Each bin
//! also kept its centroids' bounds (a second 8-lane box per axis), so a split gave its
//! children's centroid bounds, hence their grids, before the partition; nodes of at
//! least 4096 references then partitioned and binned both children in one loop (two
//! bin sets per side). Same trees bit for bit (tested against this builder at 1 and 2
//! threads), but slower: CPU ms per 1-thread build at 10^6, medians of 3 interleaved
//! rounds of 3 builds, 729 (681-739) against 697 (646-708); 10^7 one build each, 9,386
//! against 8,631 (load ~9). perf: the fused loop took 22.6 % of the samples where the
//! binning of large nodes (13 %) and their partition's share had been; per reference it
//! stores six 8-lane bin boxes and three counts where the two passes stored three and
//! three plus the reference, and the stores, not the saved read, set its pace.
//!
//! Dead end, 2026-11-24 (commit 389c6a0 on branch `build4`, reverted): nodes of at
//! least 16k references binned a sample (the first two references, one 64-byte line,
//! of every 16) to choose the split, and their partition gathered the children's
//! boxes (the sample's bins do not hold them). perf at 10^6, 1 thread: binning 22.7 ->
//! ~18 % of the samples (the sampled binning itself 1.4 %), but partition 22 -> 26 %
//! (the box-gathering kernel of the large nodes alone 12.7 %). CPU ms per build at
//! 10^6 (load 6-8, 3 interleaved rounds of 3 builds, medians): 543/483/595 before,
//! 707/678/610 sampled; 10^7 one build each, 7,588 before, 8,207 sampled. SAH cost
//! 16.0920 -> 16.1746 (+0.5 %) at 10^6, 18.5870 -> 18.6135 at 10^7; sampling from
//! 4096 or 1024 references (16.1847, 16.2096) was no faster either.
//!
//! Dead end, 2026-11-28 (issue 12, helper big19; the code is in the report of branch
//! `big19`): the interior nodes' child pairs from a bump arena instead of a `Box`
//! each (perf of `build_time 1000000 3 1`, 1 thread: `malloc`, `_int_malloc`,
//! `_int_free` and the recursive drop of the boxes were 5.4 % of the samples, 524k
//! pairs of 128 bytes per 10^6 build). One array for the worst case (`n - 1` pairs) is
//! mapped afresh by every build: page faults per build 17,547 -> 31,354, CPU ms per
//! build (7 interleaved rounds of 3 builds, load 4-6, medians) 434/431/481/565/526/
//! 524/516 before against 607/459/560/464/520/478/430. In chunks of 2048 pairs
//! (256 KiB, from glibc's heap) still 23,868 faults (the freed chunks are trimmed
//! from the heap's top) and 483/406/397/425/402/426/406 before against 434/421/407/
//! 390/464/393/429 (medians of the rounds 406 / 421): no win shows, removed. The boxes
//! come back from the heap every build; the arena's pages did not. Taken in another
//! form in session 27 (`accel::build_arena`): 16 MiB chunks advised for huge pages,
//! level with the boxes on repeated 1-thread builds as here, faster on 2-thread builds
//! and on a single build in a fresh process (numbers in that file).
//!
//! Issue 12, helper bld21, 2026-11-28 (AVX-512 host, load 5-7, 1 thread): the
//! partition's side bounds as two 8-lane [`BinBox`]es, the bins' offsets from one vector
//! conversion ([`bin_offsets`]), the sampled binning's prefetch ([`SAMPLE_AHEAD`]),
//! the sweep's negated extents, SSE4.1 ceiling and unfilled plane arrays, and the
//! reference array not zeroed before it is written. Same trees at every size. CPU ms
//! per build against the build before, interleaved (`build_time N REPS 1`, medians of
//! each round; min / median / max over the rounds): 10^6, 6 rounds of 3 builds,
//! 388.7 / 436.1 / 534.4 -> 340.8 / 377.4 / 478.4 (lower in every round; a first run of
//! 7 rounds 441.7 -> 376.7 median, lower in 6); 10^5, 6 x 7, 33.2 / 33.7 / 35.5 ->
//! 30.2 / 32.6 / 34.5; 10^7, 3 x 2, 5,786 / 5,958 / 6,812 -> 4,994 / 5,596 / 5,836.
//! Not split by change (no time for single-change builds): in perf the sampled
//! binning went from 4.7 to 2.3 % of the samples; the other shares moved within the
//! noise of single profiles.
//!
//! Dead end, issue 12, helper bld22, 2026-11-29 (commit 19abce8 on branch `bld22`,
//! reverted). perf of `build_time 10000000 2 1` (1 thread, load ~2.4): the kernel
//! zeroing fresh pages 29 % of the samples (15 % in the root's partition into the
//! fresh scratch array, 7.6 % making the references, 3.6 % the collapse's node array),
//! `partition_on_axis` 18.8 %, the sweep 8.4 %, paired binning 6.8 %. This host's L3
//! is 260 MB (shared), so a 10^6 build's two 32 MB arrays can stay in it and a 10^7
//! build's 640 MB cannot. Tried together: nodes of at least 2^18 references
//! partitioned with non-temporal stores (`movntps` through a new
//! `simd/stream_store.rs`, `sfence` after the loop: no read of each destination line
//! before it is written), and the root's bounds folded while the references are made
//! (one read of the 320 MB array fewer at 10^7). Same trees and checksums, images
//! identical (imgcheck, 30 images). Under load 7-10 (CPU ms per build, one binary
//! with the threshold from the environment, `build_time 10000000 2 1`): no streaming
//! 5,353 / 5,847, from 2^21 4,850 / 5,195, from 2^18 4,819 / 5,000; but interleaved
//! against the starting build, 3 rounds of 2 builds, CPU ms medians 5,648 / 5,932 /
//! 6,771 before against 5,317 / 6,732 / 6,590; 10^6, 6 rounds of 3, medians 465 / 456 /
//! 400 / 389 / 472 / 433 before against 445 / 408 / 388 / 424 / 439 / 496. Quiet
//! (load 1.1-2.1, 01:13-01:16 UTC), 10^7, 3 rounds of 2: wall ms medians 4,456 /
//! 4,012 / 3,762 before against 4,410 / 4,158 / 3,891, CPU ms 4,532 / 4,207 / 3,953
//! against 4,443 / 4,351 / 4,053: no win, so removed. A first-touch test of 320 MB
//! (C, `mmap` + `madvise`, three times each): 4 KiB pages 329-367 ms, huge pages
//! 161-163 ms, huge pages with `MADV_POPULATE_WRITE` 89-112 ms to populate plus
//! 103-121 ms to write: populating first does not pay for arrays that get huge pages
//! (and the first touch of memory this VM had never used took 2,866 ms, a host-side
//! cost no advice avoids).

use super::Bvh2BuildOptions;
use super::Primitives;
use super::build_arena::{Arena, ArenaRef, Cursor};
use crate::geometry::Aabb;
use crate::pages::{ALWAYS_MAPPED_BYTES, advise_huge_pages, zeroed_vec};
use crate::simd::bin_box::BinBox;
use crate::simd::bin_index;
use crate::simd::box_areas;
use crate::simd::prefetch::prefetch;
use glam::{BVec4A, Vec3A, Vec4};
use rayon::prelude::*;
use std::mem::MaybeUninit;

/// Past this depth the builder splits at the object median, so the depth of any tree
/// stays below `MEDIAN_DEPTH + 32` and a fixed traversal stack suffices.
pub(super) const MEDIAN_DEPTH: usize = 40;
/// Subtrees with fewer primitives are built on the current thread.
const PARALLEL_THRESHOLD: usize = 4096;
/// Nodes with at least this many primitives bin (and, with several threads,
/// partition) in parallel chunks of [`PARALLEL_THRESHOLD`].
const PARALLEL_NODE: usize = PARALLEL_THRESHOLD * 4;

/// A box in SIMD-friendly form for the builder (`Vec3A`: one register per corner).
#[derive(Clone, Copy, Debug)]
pub(super) struct BBox {
    min: Vec3A,
    max: Vec3A,
}

impl BBox {
    const EMPTY: BBox = BBox {
        min: Vec3A::splat(f32::INFINITY),
        max: Vec3A::splat(f32::NEG_INFINITY),
    };

    #[inline(always)]
    fn grow(&mut self, o: &BBox) {
        self.min = self.min.min(o.min);
        self.max = self.max.max(o.max);
    }

    #[inline(always)]
    fn grow_point(&mut self, p: Vec3A) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }

    #[inline(always)]
    fn union(mut self, o: &BBox) -> BBox {
        self.grow(o);
        self
    }

    #[inline(always)]
    fn area(&self) -> f32 {
        let e = (self.max - self.min).max(Vec3A::ZERO);
        2.0 * (e.x * e.y + e.y * e.z + e.z * e.x)
    }

    fn extent(&self) -> Vec3A {
        (self.max - self.min).max(Vec3A::ZERO)
    }

    fn to_aabb(self) -> Aabb {
        Aabb::new(self.min.into(), self.max.into())
    }
}

/// A primitive as the builder sees it (Embree's `PrimRef`): its box, with its index in
/// the `w` lane of `min`. 32 bytes, two SIMD loads.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(16))]
pub(super) struct PrimRef {
    min: Vec4,
    max: Vec4,
}

const _: () = assert!(std::mem::size_of::<PrimRef>() == 32);

impl PrimRef {
    fn new(b: Aabb, id: u32) -> Self {
        PrimRef {
            min: b.min.extend(f32::from_bits(id)),
            max: b.max.extend(0.0),
        }
    }

    #[inline(always)]
    fn bounds(&self) -> BBox {
        BBox {
            min: Vec3A::from_vec4(self.min),
            max: Vec3A::from_vec4(self.max),
        }
    }

    /// The box in the bins' form.
    #[inline(always)]
    fn bin_box(&self) -> BinBox {
        BinBox::new(self.min, self.max)
    }

    /// The centre of the box: `0.5 * (min + max)`, as `Aabb::center`.
    ///
    /// The id's lane is cleared first. An id read as an `f32` is a subnormal number (ids
    /// below 2^23), and halving a subnormal gives a subnormal: on Intel cores every such
    /// multiply takes a microcode assist (on the AMD host it did not show). Measured on
    /// the AVX-512 host (Intel Xeon, 2026-11-25, `build_time ../shared/models/bunny.obj 5
    /// 1`): 100-105 ms per build with the id in the sum, ~80 % of `partition_on_axis`'s
    /// and `Bins::add_all_paired`'s samples on the instructions right after this
    /// arithmetic; Embree built the same mesh in 25.8 ms.
    #[inline(always)]
    fn centroid(&self) -> Vec3A {
        Vec3A::from_vec4(self.centroid4())
    }

    /// [`PrimRef::centroid`] with its `w` lane: `0.0`.
    #[inline(always)]
    fn centroid4(&self) -> Vec4 {
        (self.min.with_w(0.0) + self.max) * 0.5
    }

    #[inline(always)]
    fn id(&self) -> u32 {
        self.min.w.to_bits()
    }
}

/// Intermediate tree of the parallel build: flattened into a BVH2, or collapsed
/// straight into a BVH4/8.
///
/// Leaf ranges are `u32` (the builder holds fewer than 2^32 primitives): a node is
/// then 48 bytes (64 with `usize` ranges), and an interior node's child pair 96 bytes
/// (a heap block of 112 with glibc's header until the pairs moved into one arena,
/// `accel::build_arena`) instead of 128 (144). At 10^7 triangles the build makes 2.6
/// million pairs. Issue 12, helper bld23, 2026-11-29: peak RSS of
/// `build_time 10000000 2 1` 185 -> 177 bytes per triangle, of `build_time 100000 9
/// 1` 500 -> 406; CPU ms per 10^7 build (medians of 2, interleaved with the build
/// before, load 4.8-8.8 with compiles running) 6,651 / 5,467 / 5,221 before against
/// 6,246 / 5,302 / 5,487: within the noise on its own.
pub(super) enum BuildNode {
    Leaf {
        bounds: BBox,
        start: u32,
        count: u32,
    },
    Interior {
        bounds: BBox,
        /// In the build's [`Arena`] (was a `Box` each: see `accel::build_arena`).
        children: ArenaRef<[BuildNode; 2]>,
    },
}

/// A finished build tree: its root and the arena holding every interior node's child
/// pair, freed together. Read through `Deref` as its root [`BuildNode`]; the nodes can
/// only be borrowed from it, so no node outlives the pairs it points to.
pub(super) struct BuildTree {
    root: BuildNode,
    _pairs: Arena<[BuildNode; 2]>,
}

impl std::ops::Deref for BuildTree {
    type Target = BuildNode;

    fn deref(&self) -> &BuildNode {
        &self.root
    }
}

const _: () = assert!(std::mem::size_of::<BuildNode>() == 48);

impl BuildNode {
    /// Surface area of the node's box.
    pub(super) fn area(&self) -> f32 {
        match self {
            BuildNode::Leaf { bounds, .. } | BuildNode::Interior { bounds, .. } => bounds.area(),
        }
    }

    pub(super) fn bounds(&self) -> Aabb {
        self.bbox().to_aabb()
    }

    fn bbox(&self) -> BBox {
        match self {
            BuildNode::Leaf { bounds, .. } | BuildNode::Interior { bounds, .. } => *bounds,
        }
    }
}

struct Builder {
    opts: Bvh2BuildOptions,
    /// `log2(block_size)` when the block size is a power of two (1 and 4 are the ones
    /// in use): [`Builder::blocks`] is then a shift. The integer division it replaces
    /// ran twice per bin and axis in the sweep, and the sweep was 10 % of a build.
    block_shift: Option<u32>,
    /// Nodes of at least this many references choose their split from a sample
    /// ([`Bins::add_sampled`]; [`SAMPLED_BINNING`] in a build, `usize::MAX` for none).
    sample_from: usize,
    /// Nodes of at least this many references partition in parallel
    /// ([`partition_parallel`]).
    parallel_from: usize,
    /// The interior nodes' child pairs.
    pairs: Arena<[BuildNode; 2]>,
}

/// Most bins per axis the builder supports (a power of two: see [`Bins::add`]).
pub(super) const MAX_BINS: usize = 32;
const _: () = assert!(MAX_BINS.is_power_of_two());

/// Per-axis bins of one node: bounds and primitive counts. The bounds are
/// [`BinBox`]es (maximum negated, one 8-lane minimum per update); [`Bins::bounds`]
/// reads one back as a [`BBox`]. The counts are kept per bin, the three axes in lanes
/// 0-2 of one `[u32; 4]` (lane 3 zero), so that the sweep loads a bin's three counts
/// as one vector ([`Bins::count`] reads one).
#[derive(Clone)]
struct Bins {
    boxes: [[BinBox; MAX_BINS]; 3],
    counts: [[u32; 4]; MAX_BINS],
}

impl Bins {
    fn new() -> Self {
        Bins {
            boxes: [[BinBox::EMPTY; MAX_BINS]; 3],
            counts: [[0; 4]; MAX_BINS],
        }
    }

    /// The box of bin `k` on `axis`.
    #[inline(always)]
    fn bounds(&self, axis: usize, k: usize) -> BBox {
        let b = &self.boxes[axis][k];
        BBox {
            min: b.min(),
            max: b.max(),
        }
    }

    /// The count of bin `k` on `axis`.
    #[inline(always)]
    fn count(&self, axis: usize, k: usize) -> u32 {
        self.counts[k][axis]
    }

    /// The counts of bin `k` on the three axes in lanes 0-2 (lane 3 zero), as floats
    /// (exact below 2^24).
    #[inline(always)]
    fn counts_f32(&self, k: usize) -> Vec4 {
        glam::UVec4::from_array(self.counts[k]).as_ivec4().as_vec4()
    }

    fn merge(mut self, o: &Bins) -> Bins {
        self.merge_first(o, MAX_BINS);
        self
    }

    /// Adds the first `n` bins of each axis of `o` to this one's.
    fn merge_first(&mut self, o: &Bins, n: usize) {
        for a in 0..3 {
            for k in 0..n {
                self.boxes[a][k].grow(&o.boxes[a][k]);
            }
        }
        for (c, o) in self.counts[..n].iter_mut().zip(&o.counts[..n]) {
            for (c, o) in c.iter_mut().zip(o) {
                *c += o;
            }
        }
    }

    /// Empties the first `n` bins of each axis (the only ones a node uses).
    fn clear(&mut self, n: usize) {
        for a in 0..3 {
            self.boxes[a][..n].fill(BinBox::EMPTY);
        }
        self.counts[..n].fill([0; 4]);
    }

    /// Adds box `b` to the bins at byte offsets `o` ([`bin_offsets`]: 16 per bin, one
    /// per axis): each axis's count and box. By offset, not index: the offsets come
    /// out of one vector conversion, and the rows' addresses need no further scaling
    /// (a box row is 32 bytes, an index register scaled by 2).
    #[inline(always)]
    fn add_at(&mut self, o: [u32; 3], b: &BinBox) {
        let counts = self.counts.as_mut_ptr().cast::<u8>();
        for (axis, &o) in o.iter().enumerate() {
            let o = o as usize;
            // SAFETY: `o` is `16 * bin` with `bin < MAX_BINS` (`bin_offsets` masks
            // it): `counts[bin][axis]` is the u32 at byte `o + 4 * axis` of `counts`
            // (rows of 16 bytes) and `boxes[axis][bin]` the box at byte `2 * o` of its
            // row (32 bytes each, so aligned as `BinBox::grow` needs).
            unsafe {
                *counts.add(o + 4 * axis).cast::<u32>() += 1;
                let row = self.boxes[axis].as_mut_ptr().cast::<u8>();
                (*row.add(2 * o).cast::<BinBox>()).grow(b);
            }
        }
    }

    /// Bins `refs` (centroids binned with `lo`, `scale`, `bins_n`).
    #[inline(always)]
    fn add_all(&mut self, refs: &[PrimRef], lo: Vec3A, scale: Vec3A, bins_n: usize) {
        for r in refs {
            let o = bin_offsets(r.centroid(), lo, scale, bins_n);
            self.add_at(o, &r.bin_box());
        }
    }

    /// As [`Bins::add_all`], alternating references between this set and `other`
    /// (cleared for `bins_n` bins), then merging `other` in: the same bins. Neighbours
    /// in a node's array often fall in the same bin, and each update of a bin waits for
    /// the previous one through memory; two sets let two chains run at once (Embree's
    /// binner bins two primitives per iteration for the same reason).
    fn add_all_paired(
        &mut self,
        other: &mut Bins,
        refs: &[PrimRef],
        lo: Vec3A,
        scale: Vec3A,
        bins_n: usize,
    ) {
        let mut pairs = refs.chunks_exact(2);
        for p in &mut pairs {
            let (a, b) = (&p[0], &p[1]);
            let ka = bin_offsets(a.centroid(), lo, scale, bins_n);
            let kb = bin_offsets(b.centroid(), lo, scale, bins_n);
            self.add_at(ka, &a.bin_box());
            other.add_at(kb, &b.bin_box());
        }
        self.add_all(pairs.remainder(), lo, scale, bins_n);
        self.merge_first(other, bins_n);
    }

    /// As [`Bins::add_all_paired`] over a sample of `refs`: the first two references
    /// of every [`SAMPLE_BLOCK`] counted from the start of `refs` (the first into this
    /// set, the second into `other`, cleared for `bins_n` bins). Counts are the
    /// sample's; [`Bins::weigh`] scales them.
    fn add_sampled(
        &mut self,
        other: &mut Bins,
        refs: &[PrimRef],
        lo: Vec3A,
        scale: Vec3A,
        bins_n: usize,
    ) {
        for (i, block) in refs.chunks(SAMPLE_BLOCK).enumerate() {
            // The sample's pair [`SAMPLE_AHEAD`] blocks on (one or two lines).
            let ahead = (i + SAMPLE_AHEAD) * SAMPLE_BLOCK;
            if let Some(pair) = refs.get(ahead..(ahead + 2).min(refs.len())) {
                for r in pair {
                    prefetch(r, 1);
                }
            }
            let a = &block[0];
            self.add_at(bin_offsets(a.centroid(), lo, scale, bins_n), &a.bin_box());
            if let Some(b) = block.get(1) {
                other.add_at(bin_offsets(b.centroid(), lo, scale, bins_n), &b.bin_box());
            }
        }
        self.merge_first(other, bins_n);
    }

    /// Multiplies the first `n` counts of each axis by `w` (a sample's weight).
    fn weigh(&mut self, n: usize, w: u32) {
        for c in self.counts[..n].iter_mut().flatten() {
            *c *= w;
        }
    }
}

/// Nodes with at least this many references bin into two sets ([`Bins::add_all_paired`]).
const PAIRED_BINNING: usize = 64;

/// Nodes with at least this many references bin a sample of them
/// ([`Bins::add_sampled`]) to choose their split, then partition all of them. Their
/// children's boxes are then the unions of the sample's bins, smaller than the true
/// ones: a child uses its box only to scale its SAH costs (the same factor for every
/// plane), gets the true box back as the union of its own children's, and below this
/// size recomputes it in one pass over its references ([`Builder::build`]).
///
/// Measured at 10^6 triangles (perf, 1 thread): binning the nodes of at least 16k
/// references was 16 % of the build, five times the cost per reference of the small
/// nodes' binning (their references come from memory, not cache).
const SAMPLED_BINNING: usize = PARALLEL_NODE;
/// The sample: the first two references (one 64-byte line) of every block of this many.
const SAMPLE_BLOCK: usize = 16;
/// Blocks ahead of the one being binned whose sampled pair [`Bins::add_sampled`]
/// prefetches. Its loads are one or two lines every 512 bytes, from memory in the top
/// levels (perf, 1 thread, `build_time 1000000 5 1`: the sampled binning was 4.7 % of
/// the samples, about four levels' worth of the in-cache binning for an eighth of the
/// references).
const SAMPLE_AHEAD: usize = 16;
/// The references each sampled one stands for in the sweep's counts.
const SAMPLE_WEIGHT: u32 = (SAMPLE_BLOCK / 2) as u32;
/// Chunk of a sampled node binned by one task (a multiple of [`SAMPLE_BLOCK`], so the
/// sample is the same whatever the chunking).
const SAMPLED_CHUNK: usize = PARALLEL_THRESHOLD * 4;
const _: () = assert!(SAMPLED_CHUNK.is_multiple_of(SAMPLE_BLOCK));

thread_local! {
    /// Bins reused by every node a thread splits: clearing the bins in use is cheaper
    /// than building 3.5 KB of bins per node, most of which are tiny.
    static SCRATCH_BINS: std::cell::RefCell<[Bins; 2]> =
        std::cell::RefCell::new([Bins::new(), Bins::new()]);
}

/// Where to split a node: axis, first bin of the right side, bin count, SAH cost.
#[derive(Clone, Copy)]
struct Split {
    axis: usize,
    bin: usize,
    bins: usize,
    cost: f32,
}

/// The chosen split with its children's boxes, read off the bins: a primitive goes
/// left exactly when its bin on the split axis is below the split bin (the same
/// [`bin_coords`] decides both), so the union of the left bins' boxes is the union of the
/// left primitives' boxes, bit for bit (min and max are exact). The partition then
/// only gathers the children's centroid bounds.
#[derive(Clone, Copy)]
struct Chosen {
    split: Split,
    left: BBox,
    right: BBox,
}

/// A node's bounds and its centroids' bounds, passed from parent to child so that
/// no pass over the primitives is spent recomputing them.
#[derive(Clone, Copy)]
struct NodeBounds {
    bounds: BBox,
    centroids: BBox,
}

impl NodeBounds {
    const EMPTY: NodeBounds = NodeBounds {
        bounds: BBox::EMPTY,
        centroids: BBox::EMPTY,
    };

    fn union(self, o: &NodeBounds) -> NodeBounds {
        NodeBounds {
            bounds: self.bounds.union(&o.bounds),
            centroids: self.centroids.union(&o.centroids),
        }
    }
}

/// The binned-SAH build itself: the tree (`None` for no primitives) and the primitive
/// order its leaf ranges index.
pub(super) fn build_tree<P: Primitives>(
    prims: &P,
    opts: Bvh2BuildOptions,
) -> (Option<BuildTree>, Vec<u32>) {
    let (tree, ids, _) = build_tree_sampling(prims, opts, SAMPLED_BINNING);
    (tree, ids)
}

/// [`build_tree`], also handing back the memory of its reference array (dead once
/// the build returns) for the caller's next array: see [`SpareRefs`].
pub(super) fn build_tree_keeping_refs<P: Primitives>(
    prims: &P,
    opts: Bvh2BuildOptions,
) -> (Option<BuildTree>, Vec<u32>, SpareRefs) {
    build_tree_sampling(prims, opts, SAMPLED_BINNING)
}

/// The memory of a finished build's reference array, whose contents are dead: an
/// array made after the build ([`SpareRefs::into_vec`]) can take over its pages
/// instead of asking the kernel for fresh ones.
///
/// Why (issue 12, helper big20, 2026-11-28, perf of `build_time 10000000 3 1`, 1
/// thread): the kernel zeroing fresh pages was 26 % of the samples and page faults
/// 34 % (every one of them: `clear_page_erms`, `folio_zero_user`); per build 163,884
/// faults, of which the collapse writing the triangle groups (420 MB at 10^7) was a
/// quarter (6.45 % of the samples). glibc maps blocks of 32 MiB and more afresh and
/// unmaps them when freed, so at 10^7 the groups' pages are new in every build, just
/// after the 320 MB of references are unmapped. Taken over: faults per 10^7 build
/// 163,884 -> 62,242, same trees. `build_time 10000000 3 1` interleaved with the build
/// before, wall ms medians: quiet (load 0.7-1.0) 4,471 / 4,141 / 4,090 before against
/// 3,941 / 4,018 / 3,992 (2.49-2.54 Mtri/s); load 1.2-2.7 4,319 / 4,191 / 5,482 /
/// 4,573 / 4,285 against 4,663 / 4,260 / 4,474 / 4,688 / 4,246 (the recycled pages
/// are not in cache, so each group's store reads its line where a fresh page was
/// zeroed just before); CPU ms under load 4.3-5.9: 6,846 / 5,971 / 7,871 / 6,009 /
/// 6,299 / 5,321 against 5,060 / 5,132 / 6,167 / 5,534 / 5,674 / 4,419.
pub(super) struct SpareRefs(Vec<PrimRef>);

/// Spare arrays smaller than this are not taken over: glibc's largest mmap threshold
/// (`DEFAULT_MMAP_THRESHOLD_MAX`, 32 MiB on 64-bit), below which blocks come from the
/// heap, where the next array gets the freed pages back anyway and growing a block in
/// place may copy it.
///
/// Tried, no win (2026-11-29, session 25): 16 MiB, so that a 10^6 build's reference
/// array (32,000,000 bytes, just under 32 MiB) is taken over too. `bench --mesh
/// /tmp/m1e6.obj --threads 2 --reps 1 --modes bvh8-packet`, build ms, 3 interleaved
/// rounds (AVX-512, host in a slow state): 199/190/206 at 32 MiB against 234/203/193.
const RECYCLE_MIN_BYTES: usize = ALWAYS_MAPPED_BYTES;

impl SpareRefs {
    /// Whether [`SpareRefs::into_vec`] takes the block over (it is large enough to be
    /// a mapping of its own) rather than allocating afresh.
    pub(super) fn recycles(&self) -> bool {
        self.0.capacity() * std::mem::size_of::<PrimRef>() >= RECYCLE_MIN_BYTES
    }

    /// An empty vector with room for `capacity` values of `T`: in the spare array's
    /// memory, resized to fit (`realloc`, which for a mapped block moves or extends
    /// its mapping without copying the pages), when the spare array is large; else a
    /// fresh allocation.
    pub(super) fn into_vec<T>(self, capacity: usize) -> Vec<T> {
        const {
            assert!(std::mem::align_of::<T>() == std::mem::align_of::<PrimRef>());
        }
        let new = std::alloc::Layout::array::<T>(capacity).expect("array size");
        let old = self.0.capacity() * std::mem::size_of::<PrimRef>();
        if old < RECYCLE_MIN_BYTES || new.size() == 0 {
            return Vec::with_capacity(capacity);
        }
        let mut refs = std::mem::ManuallyDrop::new(self.0);
        let layout = std::alloc::Layout::array::<PrimRef>(refs.capacity())
            .expect("the reference array's own layout");
        // SAFETY: `refs` owns a block of the global allocator with `layout` (a
        // non-empty Vec's buffer, never freed: `ManuallyDrop`); the new size is
        // non-zero and, being a valid `Layout`'s, at most `isize::MAX` when rounded
        // up to the alignment, which it keeps.
        let ptr =
            unsafe { std::alloc::realloc(refs.as_mut_ptr().cast::<u8>(), layout, new.size()) };
        if ptr.is_null() {
            std::alloc::handle_alloc_error(new);
        }
        // SAFETY: `ptr` is a block of the global allocator of exactly `new.size()` =
        // `capacity * size_of::<T>()` bytes, aligned as `PrimRef`, which is `T`'s
        // alignment (asserted above); the vector starts empty, so no value of `T` is
        // read from the old contents.
        unsafe { Vec::from_raw_parts(ptr.cast::<T>(), 0, capacity) }
    }
}

/// [`build_tree`] with nodes of at least `sample_from` references binned from a
/// sample (`usize::MAX`: none).
fn build_tree_sampling<P: Primitives>(
    prims: &P,
    opts: Bvh2BuildOptions,
    sample_from: usize,
) -> (Option<BuildTree>, Vec<u32>, SpareRefs) {
    assert!(
        opts.bins >= 2 && opts.bins <= MAX_BINS,
        "bins must be in 2..={MAX_BINS}"
    );
    let n = prims.count();
    assert!(
        u32::try_from(n).is_ok(),
        "at most 2^32 - 1 primitives per structure"
    );
    // Written in full here, so not zeroed first: `calloc` clears a block recycled from
    // the heap with `memset` (the 32 MB arrays of a 10^6 build are; `memset` was 1.5 %
    // of a 1-thread build's perf samples, `build_time 1000000 5 1`, for both arrays).
    let mut refs = Vec::<PrimRef>::with_capacity(n);
    advise_huge_pages(refs.as_mut_ptr().cast(), n * std::mem::size_of::<PrimRef>());
    refs.spare_capacity_mut()[..n]
        .par_chunks_mut(PARALLEL_THRESHOLD)
        .enumerate()
        .for_each(|(c, chunk)| {
            let first = c * PARALLEL_THRESHOLD;
            for (k, r) in chunk.iter_mut().enumerate() {
                let i = first + k;
                r.write(PrimRef::new(prims.bounds(i), i as u32));
            }
        });
    // SAFETY: the capacity is `n` (`with_capacity`'s guarantee) and the loop above
    // wrote each of the first `n` slots.
    unsafe { refs.set_len(n) };
    let mut ids = zeroed_ids(n);
    if n == 0 {
        return (None, ids, SpareRefs(refs));
    }
    // Written in full by the root's partition before anything reads it: no copy.
    let mut scratch = zeroed_refs(n);
    let bs = opts.block_size.max(1);
    let builder = Builder {
        opts,
        block_shift: bs.is_power_of_two().then(|| bs.trailing_zeros()),
        sample_from: sample_from.max(opts.max_leaf + 1),
        parallel_from: parallel_partition_from(n),
        // At most one interior node fewer than leaves, and at most `n` leaves.
        pairs: Arena::new(n - 1),
    };
    let nb = node_bounds(&refs);
    let mut cursor = Cursor::empty();
    let root = builder.build(
        &mut refs,
        &mut scratch,
        &mut ids,
        0,
        0,
        nb,
        true,
        &mut cursor,
    );
    let tree = BuildTree {
        root,
        _pairs: builder.pairs,
    };
    (Some(tree), ids, SpareRefs(refs))
}

/// The smallest node that partitions in parallel in a build over `n` references: one
/// that holds at least a thread's share of them (at 2 threads the root, and a child
/// only of a split more uneven than half and half), and never one below
/// [`PARALLEL_NODE`]. Below that share the subtrees already keep every thread busy
/// (`rayon::join` in [`Builder::build`]), and the parallel partition's count pass
/// reads every reference once more: at 10^7 triangles and 2 threads that pass
/// (`count_on_axis`) was 12.5 % of a build's samples (`perf record -e cpu-clock` of
/// `examples/build_time 10000000 3 2`), against 19.9 % for the writes.
///
/// Measured (issue 12, session 27, AVX-512, 2 threads, the share switched by an
/// environment variable in one binary, interleaved rounds): `build_time 10000000 3 2`,
/// CPU ms medians 3,942 / 3,929 with a parallel partition at every node of
/// [`PARALLEL_NODE`] and more, against 3,502 / 3,541 with this share (and 3,565 / 3,683
/// with half a share); wall 1,803 ms (2.77 Mtriangles/s per thread) in the round where
/// the build had both cores (the other round shared one core with a compile), against
/// 2,038 ms (2.45 per thread) for `build_time 10000000 5 2` at 14:01. `build_time 1000000 7 2`, 3 rounds: wall medians 174.8 / 173.4 / 182.2
/// against 163.3 / 168.7 / 163.7 ms. `build_time 100000 15 2`: level (12.6-13.1 ms
/// either way). The same trees: the serial and the parallel partition write the same
/// order (`parallel_partition_matches_the_serial_one`). Session 24 had tried the root alone at
/// 2 threads and measured it level at 10^6 (wall 187.6-204.2 against 192.5-197.8 ms, a
/// noisier window); the count pass grows with the levels a build has above the share.
fn parallel_partition_from(n: usize) -> usize {
    (n / rayon::current_num_threads()).max(PARALLEL_NODE)
}

/// `n` zeroed references, allocated without being written (`calloc`: fresh pages from
/// the kernel are already zero) and, on Linux, marked for transparent huge pages
/// before their first touch where [`advise_huge_pages`] says so.
///
/// Measured before (README "BVH build"): page faults were 5 % of a 1-thread build at
/// 10^6 triangles, and the scratch array was a full copy of the references.
///
/// Why 10^7 builds slower per triangle than 10^6 (2026-11-24, perf, 1 thread, load
/// 8-9; no hardware counters in this VM, so no cache-miss counts): the kernel zeroing
/// fresh pages was 19 % of the samples at 10^7 against 4 % at 10^6. glibc maps blocks
/// above 32 MB afresh and unmaps them when freed, so every 10^7 build gets its 640 MB
/// of references as fresh pages, while at 10^6 the 64 MB pair is recycled from the
/// heap by the next build. With the allocator kept from mapping (`MALLOC_MMAP_MAX_=0`,
/// an experiment only) one 10^7 build took 5,919 CPU ms against 7,353 and 14.5 s wall
/// against 53.9 s. Not built yet: partitioning the top levels in place (no scratch
/// array: 32 bytes per triangle fewer fresh pages; it changes the order of references,
/// hence the sampled splits).
fn zeroed_refs(n: usize) -> Vec<PrimRef> {
    if n == 0 {
        return Vec::new();
    }
    let layout = std::alloc::Layout::array::<PrimRef>(n).expect("reference array size");
    if layout.size() >= ALWAYS_MAPPED_BYTES {
        // SAFETY: all-zero bytes are a valid PrimRef (four 0.0 lanes twice).
        return unsafe { zeroed_vec(n) };
    }
    // A smaller block may come from the heap, which `calloc` clears with `memset`
    // before the advice could be given: advised first, then zeroed here (in parallel
    // chunks). Issue 12, helper bc28, session 28: at 10^6 (32,000,000 bytes, just under
    // glibc's largest mmap threshold) that `memset` faulted the block in 4 KiB at a
    // time, ~5,500 of the ~7,800 page faults per build (`perf record -e page-faults`
    // of `build_time 1000000 3 2`).
    let mut v = Vec::<PrimRef>::with_capacity(n);
    advise_huge_pages(v.as_mut_ptr().cast(), layout.size());
    let zero = PrimRef {
        min: Vec4::ZERO,
        max: Vec4::ZERO,
    };
    v.spare_capacity_mut()[..n]
        .par_chunks_mut(PARALLEL_THRESHOLD * 4)
        .for_each(|c| c.fill(MaybeUninit::new(zero)));
    // SAFETY: the capacity is at least `n`, and the loop wrote each of the first `n`.
    unsafe { v.set_len(n) };
    v
}

/// `n` zeroed primitive indices (the build's output order), advised for huge pages
/// before their first touch as the reference arrays are ([`zeroed_refs`]).
///
/// Why (issue 12, helper bc28, session 28): as `vec![0u32; n]` the array (40 MB at
/// 10^7, a fresh mapping from glibc in every build) was faulted in 4 KiB at a time by
/// the leaves' writes, ~9,800 faults per 10^7 build, most of the ~7,500-10,000 that
/// `examples/build_time 10000000 3 2` counted per build (`perf record -e page-faults`:
/// the leaf closure of `Builder::build` and the arena's chunks, `accel::build_arena`);
/// in the host's slow state a fresh 4 KiB page costs 5-40 us to touch.
fn zeroed_ids(n: usize) -> Vec<u32> {
    // SAFETY: all-zero bytes are a valid u32.
    unsafe { zeroed_vec(n) }
}

/// Bounds and centroid bounds of `refs`.
fn node_bounds(refs: &[PrimRef]) -> NodeBounds {
    let fold = |mut acc: NodeBounds, r: &PrimRef| {
        acc.bounds.grow(&r.bounds());
        acc.centroids.grow_point(r.centroid());
        acc
    };
    if refs.len() >= PARALLEL_NODE {
        refs.par_chunks(PARALLEL_THRESHOLD)
            .map(|c| c.iter().fold(NodeBounds::EMPTY, fold))
            .reduce(|| NodeBounds::EMPTY, |a, b| a.union(&b))
    } else {
        refs.iter().fold(NodeBounds::EMPTY, fold)
    }
}

/// The bin coordinates of a centroid on all three axes, clamped to `[0, bins - 1]`:
/// the bins are their truncations ([`bin_offsets`]).
#[inline(always)]
fn bin_coords(c: Vec3A, lo: Vec3A, scale: Vec3A, bins: usize) -> Vec3A {
    // Clamped on both sides, and min/max return the non-NaN operand, so every lane is
    // finite and in [0, bins - 1] even for a NaN centroid.
    ((c - lo) * scale)
        .max(Vec3A::ZERO)
        .min(Vec3A::splat((bins - 1) as f32))
}

/// The bins of a centroid on all three axes as byte offsets, `16 * bin` (for
/// [`Bins::add_at`]), masked below [`MAX_BINS`] (the clamp already keeps them below
/// `bins <= MAX_BINS`; the mask makes the bins' unchecked addressing safe whatever the
/// input).
///
/// Measured before (perf, 1 thread, `build_time 1000000 5 1`): the binning loops
/// were 17 % of a build's samples while each axis's bin was converted to an integer
/// on its own (`vcvttss2usi` and a shuffle), masked and scaled twice (for the counts'
/// row and the box's).
#[inline(always)]
fn bin_offsets(c: Vec3A, lo: Vec3A, scale: Vec3A, bins: usize) -> [u32; 3] {
    bin_index::offsets16(bin_coords(c, lo, scale, bins), MAX_BINS as u32 - 1)
}

/// Bin indices of a centroid on all three axes at once (the tests' reference for
/// [`bin_offsets`]).
#[cfg(test)]
fn bins_of(c: Vec3A, lo: Vec3A, scale: Vec3A, bins: usize) -> [usize; 3] {
    let k = bin_coords(c, lo, scale, bins);
    [k.x as usize, k.y as usize, k.z as usize]
}

fn bin_scale(cb: &BBox, bins: usize) -> Vec3A {
    let e = cb.extent();
    Vec3A::select(
        e.cmpgt(Vec3A::ZERO),
        Vec3A::splat(bins as f32) / e,
        Vec3A::ZERO,
    )
}

impl Builder {
    /// Builds the subtree over `refs` (which start at global offset `offset`), using
    /// `scratch` (as long as `refs`) for the partition and writing the primitive order
    /// into `ids` (as long as `refs`). `exact` tells whether `nb.bounds` is the
    /// references' box or (below a sampled node) a box inside it.
    #[allow(clippy::too_many_arguments)]
    fn build(
        &self,
        refs: &mut [PrimRef],
        scratch: &mut [PrimRef],
        ids: &mut [u32],
        offset: usize,
        depth: usize,
        mut nb: NodeBounds,
        exact: bool,
        cursor: &mut Cursor<[BuildNode; 2]>,
    ) -> BuildNode {
        let n = refs.len();
        let sampled = n >= self.sample_from;
        if !exact && !sampled {
            // Below a sampled node: the true box, before any leaf or bin uses it.
            nb.bounds = node_bounds(refs).bounds;
        }
        let mut leaf = |refs: &[PrimRef]| {
            for (o, r) in ids.iter_mut().zip(refs) {
                *o = r.id();
            }
            // Below 2^32: `build_tree_sampling` asserts the primitive count is.
            BuildNode::Leaf {
                bounds: nb.bounds,
                start: offset as u32,
                count: n as u32,
            }
        };
        if n == 1 {
            return leaf(refs);
        }
        // Any split costs at least `traversal_cost` (the area terms are not negative), so
        // a leaf that costs no more is the SAH's answer without binning: the same tree,
        // and a third fewer nodes binned for 4-wide leaves (every 1-4 triangle leaf).
        if n <= self.opts.max_leaf
            && self.opts.intersection_cost * self.blocks(n as u32) <= self.opts.traversal_cost
        {
            return leaf(refs);
        }

        let sah = depth < MEDIAN_DEPTH && nb.centroids.extent().max_element() > 0.0;
        let mut split = None;
        if let Some(c) = sah.then(|| self.best_split(refs, &nb)).flatten() {
            let leaf_cost = self.opts.intersection_cost * self.blocks(n as u32);
            if n <= self.opts.max_leaf && leaf_cost <= c.split.cost {
                return leaf(refs);
            }
            let (m, lc, rc) = partition(refs, scratch, &nb.centroids, c.split, self.parallel_from);
            if m > 0 && m < n {
                let left = NodeBounds {
                    bounds: c.left,
                    centroids: lc,
                };
                let right = NodeBounds {
                    bounds: c.right,
                    centroids: rc,
                };
                split = Some((m, left, right));
            }
        }
        // The children's references: in `scratch` after a partition (the arrays swap
        // roles), in `refs` after the median split. A sampled node's children get the
        // sample's boxes, which are not theirs.
        let (mid, left, right, exact_kids, (data, spare)) = match split {
            Some((m, l, r)) => (m, l, r, !sampled, (scratch, refs)),
            None => {
                if n <= self.opts.max_leaf {
                    return leaf(refs);
                }
                // No useful SAH split (identical centroids, or too deep): object median
                // along the widest centroid axis, which always makes progress.
                let e = nb.centroids.extent();
                let axis = if e.x >= e.y && e.x >= e.z {
                    0
                } else if e.y >= e.z {
                    1
                } else {
                    2
                };
                let m = n / 2;
                refs.select_nth_unstable_by(m, |a, b| {
                    a.centroid()[axis].total_cmp(&b.centroid()[axis])
                });
                let (l, r) = (node_bounds(&refs[..m]), node_bounds(&refs[m..]));
                (m, l, r, true, (refs, scratch))
            }
        };

        let (ld, rd) = data.split_at_mut(mid);
        let (ls, rs) = spare.split_at_mut(mid);
        let (li, ri) = ids.split_at_mut(mid);
        let e = exact_kids;
        // A subtree handed to another task claims its own blocks of pair slots.
        let (l, r) = if n >= PARALLEL_THRESHOLD {
            rayon::join(
                || self.build(ld, ls, li, offset, depth + 1, left, e, cursor),
                || {
                    let mut own = Cursor::empty();
                    self.build(rd, rs, ri, offset + mid, depth + 1, right, e, &mut own)
                },
            )
        } else {
            (
                self.build(ld, ls, li, offset, depth + 1, left, e, cursor),
                self.build(rd, rs, ri, offset + mid, depth + 1, right, e, cursor),
            )
        };
        // An exact box is its children's union; an inexact one is rebuilt as that.
        let bounds = if exact {
            nb.bounds
        } else {
            l.bbox().union(&r.bbox())
        };
        BuildNode::Interior {
            bounds,
            // SAFETY: the pair is read only through the `BuildTree` that will own the
            // arena (`build_tree_sampling`), which lends its nodes out by reference.
            children: unsafe { self.pairs.push(cursor, [l, r]) },
        }
    }

    /// Leaf test units for `n` primitives: started blocks of `block_size`.
    #[inline(always)]
    fn blocks(&self, n: u32) -> f32 {
        match self.block_shift {
            // n < 2^32 - block_size: the builder holds fewer than 2^32 primitives and
            // block sizes are small, so the sum does not wrap.
            Some(shift) => ((n + (1 << shift) - 1) >> shift) as f32,
            None => n.div_ceil(self.opts.block_size as u32) as f32,
        }
    }

    /// Bins centroids on all three axes and sweeps for the cheapest plane.
    fn best_split(&self, refs: &[PrimRef], nb: &NodeBounds) -> Option<Chosen> {
        // Small nodes need few bins: at most two per primitive.
        // Measured and not taken, twice: Embree's count, min(32, 4 + n / 20), builds
        // faster for a higher SAH cost and 3 % more leaves. 2026-11-23: bunny 34-35 ms
        // against 38-41 ms, SAH 10.770 vs 10.744 (16.159 vs 16.092 at 10^6).
        // 2026-11-24 (with `BinBox` bins, load 8, CPU ms per build, medians of 3-6
        // interleaved rounds): bunny 35.1 vs 39.3, 10^5 38.5 vs 43.5, 10^6 ~525 vs
        // ~560; but `bench` bvh8-packet primary on the bunny gave a median of 4.00
        // against 4.85 Mrays/s over 7 interleaved rounds (noisy, cpu share 0.2, yet
        // lower in 5 of 7), so the trees were kept as they were.
        let bins_n = self.opts.bins.min(refs.len().max(4));
        let cb = &nb.centroids;
        let scale = bin_scale(cb, bins_n);
        let sampled = refs.len() >= self.sample_from;
        // Sampled counts are weighed, so they may exceed the node's by a block.
        let most = refs.len() + SAMPLE_BLOCK;
        if refs.len() >= PARALLEL_NODE {
            let chunk = if sampled {
                SAMPLED_CHUNK
            } else {
                PARALLEL_THRESHOLD
            };
            let mut bins = refs
                .par_chunks(chunk)
                .map(|chunk| {
                    let (mut bins, mut other) = (Bins::new(), Bins::new());
                    if sampled {
                        bins.add_sampled(&mut other, chunk, cb.min, scale, bins_n);
                    } else {
                        bins.add_all_paired(&mut other, chunk, cb.min, scale, bins_n);
                    }
                    bins
                })
                .reduce(Bins::new, |a, b| a.merge(&b));
            if sampled {
                bins.weigh(bins_n, SAMPLE_WEIGHT);
            }
            self.sweep(&bins, bins_n, nb, most)
        } else {
            SCRATCH_BINS.with_borrow_mut(|[bins, other]| {
                bins.clear(bins_n);
                if sampled {
                    other.clear(bins_n);
                    bins.add_sampled(other, refs, cb.min, scale, bins_n);
                    bins.weigh(bins_n, SAMPLE_WEIGHT);
                } else if refs.len() >= PAIRED_BINNING {
                    other.clear(bins_n);
                    bins.add_all_paired(other, refs, cb.min, scale, bins_n);
                } else {
                    bins.add_all(refs, cb.min, scale, bins_n);
                }
                self.sweep(bins, bins_n, nb, most)
            })
        }
    }

    /// The SAH sweep over filled bins: the cheapest plane on any axis, and the boxes of
    /// its two sides. [`Builder::sweep_lanes`] where it gives the same answer (leaf
    /// blocks by shift, counts exact in f32), else [`Builder::sweep_scalar`].
    fn sweep(&self, bins: &Bins, bins_n: usize, nb: &NodeBounds, n: usize) -> Option<Chosen> {
        match self.block_shift {
            Some(shift) if n < LANE_SWEEP_MAX => self.sweep_lanes(bins, bins_n, nb, shift),
            _ => self.sweep_scalar(bins, bins_n, nb),
        }
    }

    /// The sweep with the three axes in the lanes of one vector: each step grows three
    /// boxes, then takes their areas, leaf blocks and costs four lanes at a time
    /// (Embree's binner sweeps its axes in SIMD lanes the same way). Each lane repeats
    /// [`Builder::sweep_scalar`]'s arithmetic in the same order, and keeps the first
    /// of equal costs; the lanes are then compared in axis order, so the split is the
    /// scalar sweep's (equal unless a cost is NaN, which needs infinite coordinates).
    /// Counts are kept as f32 (exact below 2^24 = [`LANE_SWEEP_MAX`]) and
    /// `ceil(count / 2^shift)` is the started blocks exactly.
    ///
    /// Measured: the scalar sweep was 13 % of a 1-thread build at 10^6 triangles.
    fn sweep_lanes(
        &self,
        bins: &Bins,
        bins_n: usize,
        nb: &NodeBounds,
        shift: u32,
    ) -> Option<Chosen> {
        let scale = bin_scale(&nb.centroids, bins_n);
        let inv_area = 1.0 / nb.bounds.area().max(f32::MIN_POSITIVE);
        let inv_block = Vec4::splat(1.0 / (1u32 << shift) as f32);
        let axis_ok = Vec4::new(scale.x, scale.y, scale.z, 0.0).cmpne(Vec4::ZERO);
        // Planes 1..bins_n: written by the first loop, read by the second. Not
        // zero-filled first (1 KB of stores per node, most nodes using a few bins).
        let mut right_term = [MaybeUninit::<Vec4>::uninit(); MAX_BINS];
        let mut right_count = [MaybeUninit::<Vec4>::uninit(); MAX_BINS];
        let (mut acc, mut cnt) = ([BinBox::EMPTY; 3], Vec4::ZERO);
        for k in (1..bins_n).rev() {
            for (a, b) in acc.iter_mut().enumerate() {
                b.grow(&bins.boxes[a][k]);
            }
            cnt += bins.counts_f32(k);
            right_term[k].write(areas3(&acc) * box_areas::ceil(cnt * inv_block));
            right_count[k].write(cnt);
        }
        let (tc, ic) = (
            Vec4::splat(self.opts.traversal_cost),
            Vec4::splat(self.opts.intersection_cost),
        );
        let inv = Vec4::splat(inv_area);
        let (mut best, mut best_k, mut found) = (Vec4::ZERO, Vec4::ZERO, BVec4A::splat(false));
        let (mut acc, mut cnt) = ([BinBox::EMPTY; 3], Vec4::ZERO);
        for k in 1..bins_n {
            for (a, b) in acc.iter_mut().enumerate() {
                b.grow(&bins.boxes[a][k - 1]);
            }
            cnt += bins.counts_f32(k - 1);
            // SAFETY: the first loop wrote planes 1..bins_n, and 1 <= k < bins_n.
            let (right_count, right_term) =
                unsafe { (right_count[k].assume_init(), right_term[k].assume_init()) };
            let valid = axis_ok & cnt.cmpne(Vec4::ZERO) & right_count.cmpne(Vec4::ZERO);
            let left_term = areas3(&acc) * box_areas::ceil(cnt * inv_block);
            let cost = tc + ic * (left_term + right_term) * inv;
            let take = valid & (!found | cost.cmplt(best));
            best = Vec4::select(take, cost, best);
            best_k = Vec4::select(take, Vec4::splat(k as f32), best_k);
            found |= valid;
        }
        let (costs, ks, found) = (best.to_array(), best_k.to_array(), found.bitmask());
        let mut split: Option<Split> = None;
        for axis in 0..3 {
            if found & (1 << axis) != 0 && split.is_none_or(|s| costs[axis] < s.cost) {
                split = Some(Split {
                    axis,
                    bin: ks[axis] as usize,
                    bins: bins_n,
                    cost: costs[axis],
                });
            }
        }
        split.map(|s| chosen(bins, s))
    }

    /// The sweep one axis and one plane at a time (the reference for
    /// [`Builder::sweep_lanes`], and the sweep for block sizes that are not powers of
    /// two and nodes of 2^24 references or more).
    fn sweep_scalar(&self, bins: &Bins, bins_n: usize, nb: &NodeBounds) -> Option<Chosen> {
        let scale = bin_scale(&nb.centroids, bins_n);

        let inv_area = 1.0 / nb.bounds.area().max(f32::MIN_POSITIVE);
        // The best plane as plain scalars (an `Option<Split>` compared and rewritten in
        // the inner loop kept it in memory); the first of equal costs wins, as before.
        let (mut found, mut best_cost, mut best_axis, mut best_bin) = (false, 0.0f32, 0, 0);
        // Right side's area times its leaf blocks per plane, and whether it is empty.
        let mut right_term = [0.0f32; MAX_BINS];
        let mut right_empty = [true; MAX_BINS];
        for axis in 0..3 {
            if scale[axis] == 0.0 {
                continue;
            }
            let (mut acc, mut cnt) = (BBox::EMPTY, 0);
            for k in (1..bins_n).rev() {
                acc.grow(&bins.bounds(axis, k));
                cnt += bins.count(axis, k);
                right_term[k] = acc.area() * self.blocks(cnt);
                right_empty[k] = cnt == 0;
            }
            let (mut acc, mut cnt) = (BBox::EMPTY, 0);
            for k in 1..bins_n {
                acc.grow(&bins.bounds(axis, k - 1));
                cnt += bins.count(axis, k - 1);
                if cnt == 0 || right_empty[k] {
                    continue;
                }
                let cost = self.opts.traversal_cost
                    + self.opts.intersection_cost
                        * (acc.area() * self.blocks(cnt) + right_term[k])
                        * inv_area;
                if !found || cost < best_cost {
                    (found, best_cost, best_axis, best_bin) = (true, cost, axis, k);
                }
            }
        }
        found
            .then_some(Split {
                axis: best_axis,
                bin: best_bin,
                bins: bins_n,
                cost: best_cost,
            })
            .map(|split| chosen(bins, split))
    }
}

/// Nodes with fewer references sweep in lanes ([`Builder::sweep_lanes`]): their counts
/// are exact in f32.
const LANE_SWEEP_MAX: usize = 1 << 24;

/// The areas of three bin boxes in the first three lanes, each as [`BBox::area`]
/// computes it, bit for bit: [`box_areas::areas3`] of the negated extents
/// ([`BinBox::neg_extent`], two operations where [`BinBox::extent`] takes three), whose
/// pairwise products are those of the extents (`(-x) * (-y) = x * y` exactly).
///
/// Measured (perf, 1 thread, 10^6 triangles): the lane sweep was 14 % of a build
/// while it grew plain boxes read back from the bins (a negation each) and gathered
/// the extents and the counts into lanes one scalar at a time; 11.5 % before the
/// negated extents (`build_time 1000000 5 1`, 2026-11-28).
#[inline(always)]
fn areas3(b: &[BinBox; 3]) -> Vec4 {
    box_areas::areas3(b[0].neg_extent(), b[1].neg_extent(), b[2].neg_extent())
}

/// Split `split` with its two sides' boxes, the unions of its bins on either side.
fn chosen(bins: &Bins, split: Split) -> Chosen {
    // Grown as bin boxes and read back once: the same corners as a fold of the bins'
    // plain boxes (`BinBox::grow` is `min`/`max` bit for bit), one 8-lane minimum per
    // bin where the fold negated each bin's maximum back first.
    let side = |r: std::ops::Range<usize>| {
        let mut b = BinBox::EMPTY;
        for k in r {
            b.grow(&bins.boxes[split.axis][k]);
        }
        BBox {
            min: b.min(),
            max: b.max(),
        }
    };
    Chosen {
        split,
        left: side(0..split.bin),
        right: side(split.bin..split.bins),
    }
}

/// The split plane of `s` on its axis, as one partition loop tests it: the centroid's
/// bin coordinate `(c - lo) * scale`, clamped to `[0, bins - 1]` as [`bin_coords`]
/// clamps it (same operations, so the same value), compared with the split bin. For a
/// whole number `bin` and `k >= 0`, `k < bin` exactly when `trunc(k) < bin`, so the
/// float compare gives the binning's answer without the conversion to an integer.
#[derive(Clone, Copy)]
struct Plane {
    lo: f32,
    scale: f32,
    max_bin: f32,
    bin: f32,
}

impl Plane {
    fn new(lo: Vec3A, scale: Vec3A, s: Split) -> Plane {
        Plane {
            lo: lo[s.axis],
            scale: scale[s.axis],
            max_bin: (s.bins - 1) as f32,
            bin: s.bin as f32,
        }
    }

    /// The clamped bin coordinate of `x` (finite even for NaN: f32::max/min return the
    /// non-NaN operand).
    #[inline(always)]
    fn coord(&self, x: f32) -> f32 {
        ((x - self.lo) * self.scale).max(0.0).min(self.max_bin)
    }
}

/// The centroid's coordinate on axis `AXIS` (a constant lane, no indexing through
/// memory: indexing by a run-time axis stored the centroid to the stack and read one
/// lane back on every reference).
#[inline(always)]
fn lane4<const AXIS: usize>(c: Vec4) -> f32 {
    match AXIS {
        0 => c.x,
        1 => c.y,
        _ => c.z,
    }
}

/// Whether a reference goes to the left of split `s`.
#[cfg(test)]
fn goes_left(r: &PrimRef, lo: Vec3A, scale: Vec3A, s: Split) -> bool {
    let p = Plane::new(lo, scale, s);
    p.coord(r.centroid()[s.axis]) < p.bin
}

/// Centroid bounds of both sides of a plane, grown through a lane mask per reference
/// (no branch): the one accumulation [`partition_kernel`] and [`count_on_axis`] share.
/// Each side is a [`BinBox`] (minimum and negated maximum in eight lanes), grown by the
/// centroid on the side it goes to ([`BinBox::grow_either`]).
///
/// Measured before (perf, 1 thread, 10^6 triangles, `build_time 1000000 5 1`): the
/// partition was 26 % of a build's samples while the sides' bounds took four 4-lane
/// selects and four minimums or maximums per reference.
struct SideBounds {
    left: BinBox,
    right: BinBox,
}

impl SideBounds {
    #[inline(always)]
    fn new() -> Self {
        SideBounds {
            left: BinBox::EMPTY,
            right: BinBox::EMPTY,
        }
    }

    /// Adds centroid `c` (lane 3 zero, as [`PrimRef::centroid4`]) to the left side
    /// where `k < bin`, else to the right.
    #[inline(always)]
    fn add(&mut self, k: f32, bin: f32, c: Vec4) {
        BinBox::grow_either(&mut self.left, &mut self.right, BinBox::new(c, c), k, bin);
    }

    /// The left and right centroid boxes.
    #[inline(always)]
    fn boxes(self) -> (BBox, BBox) {
        let b = |s: BinBox| BBox {
            min: s.min(),
            max: s.max(),
        };
        (b(self.left), b(self.right))
    }
}

/// Writes the references of `src` left of the plane to `left` from its start in
/// order, the others to `right` from its end backwards, and gathers both sides'
/// centroid bounds. Every reference is stored once, to whichever of the two next
/// slots its side picks (a conditional move, no branch: the side is a coin flip to
/// the branch predictor), and the bounds grow through masks; all of it stays in
/// registers.
///
/// # Safety
/// `left` and `right` must be valid for writes of `src.len()` references from `left`
/// forwards and from `right_end` backwards together: for the serial partition both
/// are `dst`, with `right_end = dst + n`; for a chunk of the parallel one, its two
/// parts, exactly as long as its two sides.
#[inline(always)]
unsafe fn partition_kernel<const AXIS: usize>(
    src: &[PrimRef],
    left: *mut PrimRef,
    right_end: *mut PrimRef,
    p: Plane,
) -> (usize, BBox, BBox) {
    let mut sides = SideBounds::new();
    let (mut nl, mut nr) = (0usize, 0usize);
    for r in src {
        let c = r.centroid4();
        let k = p.coord(lane4::<AXIS>(c));
        let is_left = k < p.bin;
        // SAFETY: the caller's contract: fewer than `src.len()` references are placed,
        // so `nl` and `nr + 1` stay within the room on each side.
        let at = if is_left {
            unsafe { left.add(nl) }
        } else {
            unsafe { right_end.sub(nr + 1) }
        };
        unsafe { at.write(*r) };
        nl += usize::from(is_left);
        nr += usize::from(!is_left);
        sides.add(k, p.bin, c);
    }
    let (l, r) = sides.boxes();
    (nl, l, r)
}

/// [`partition_kernel`] for the split axis of `s`.
///
/// # Safety
/// As [`partition_kernel`].
unsafe fn partition_on_axis(
    src: &[PrimRef],
    left: *mut PrimRef,
    right_end: *mut PrimRef,
    axis: usize,
    p: Plane,
) -> (usize, BBox, BBox) {
    // SAFETY: forwarded from the caller.
    unsafe {
        match axis {
            0 => partition_kernel::<0>(src, left, right_end, p),
            1 => partition_kernel::<1>(src, left, right_end, p),
            _ => partition_kernel::<2>(src, left, right_end, p),
        }
    }
}

/// Counts the references of `src` left of the plane and gathers both sides' centroid
/// bounds (the parallel partition's first pass).
fn count_on_axis<const AXIS: usize>(src: &[PrimRef], p: Plane) -> (usize, BBox, BBox) {
    let mut sides = SideBounds::new();
    let mut nl = 0usize;
    for r in src {
        let c = r.centroid4();
        let k = p.coord(lane4::<AXIS>(c));
        nl += usize::from(k < p.bin);
        sides.add(k, p.bin, c);
    }
    let (l, r) = sides.boxes();
    (nl, l, r)
}

/// Writes the references of `src` whose centroid bin is below the split bin to the
/// front of `dst` in order, the others to the back in reverse order, and gathers both
/// sides' centroid bounds on the way (their boxes come from the bins: [`Chosen`]).
/// Returns the left count and the centroid bounds.
///
/// Serial: [`partition_kernel`] over the whole node. In parallel (nodes of at least
/// `parallel_from`: [`parallel_partition_from`] in a build, never below
/// [`PARALLEL_NODE`], with more than one thread): chunks count their sides first, then
/// each writes its part of both sides with the same kernel, to the same places the
/// serial loop would.
///
/// Tried in session 24 and measured level at 10^6 then; taken in session 27 in another
/// form, measured at 10^7 ([`parallel_partition_from`]): the parallel partition only where the levels
/// above leave threads idle (`1 << depth < threads`: at 2 threads the root alone), on
/// the guess that its two passes (count, then write) double the work where as many
/// subtrees as threads are built at once. Same trees; `build_time 1000000 7 2`, 3
/// interleaved rounds, quiet: wall medians 197.1 / 204.2 / 187.6 ms before, 195.9 /
/// 197.8 / 192.5 after; CPU 339.6 / 362.1 / 333.9 against 347.5 / 345.1 / 340.4. The 2-thread
/// build's extra ~80 CPU ms (255 -> 337 against 1 thread) and its 1.30x speed-up
/// (Embree's: 1.92x) come from elsewhere; a timeline of `perf script` samples put ~50
/// ms of each 2-thread build on one thread after the collapse (page faults of fresh
/// arrays, `Bvh::build`'s final copy, the build tree's drop; the copy and the drop
/// went in session 25: `Collapse::collapse_parallel`, `BuildNode::drop_in_parallel`).
///
/// Dead end, measured at 1 thread on 10^6 triangles (perf): the previous loop stored
/// each reference twice (to the next left and the next right slot), indexed the
/// centroid by a run-time axis (through the stack) and kept its bounds and cursor on
/// the stack; it was the largest single cost of the build (a third of its samples).
fn partition(
    src: &[PrimRef],
    dst: &mut [PrimRef],
    cb: &BBox,
    s: Split,
    parallel_from: usize,
) -> (usize, BBox, BBox) {
    assert_eq!(
        src.len(),
        dst.len(),
        "partition into an array of the same length"
    );
    let scale = bin_scale(cb, s.bins);
    let n = src.len();
    if n >= parallel_from && rayon::current_num_threads() > 1 {
        return partition_parallel(src, dst, cb.min, scale, s);
    }
    let p = Plane::new(cb.min, scale, s);
    let left = dst.as_mut_ptr();
    // SAFETY: `dst` holds `n` references: the lefts fill it from the front, the rights
    // from the back, `n` in all.
    unsafe { partition_on_axis(src, left, left.add(n), s.axis, p) }
}

/// The parallel partition: the same output as the serial loop of [`partition`].
fn partition_parallel(
    src: &[PrimRef],
    dst: &mut [PrimRef],
    lo: Vec3A,
    scale: Vec3A,
    s: Split,
) -> (usize, BBox, BBox) {
    let p = Plane::new(lo, scale, s);
    // Pass 1: per chunk, the left count and both sides' centroid bounds.
    let counts: Vec<(usize, BBox, BBox)> = src
        .par_chunks(PARALLEL_THRESHOLD)
        .map(|chunk| match s.axis {
            0 => count_on_axis::<0>(chunk, p),
            1 => count_on_axis::<1>(chunk, p),
            _ => count_on_axis::<2>(chunk, p),
        })
        .collect();
    let mid: usize = counts.iter().map(|c| c.0).sum();
    let (left, right) = counts.iter().fold((BBox::EMPTY, BBox::EMPTY), |(a, b), c| {
        (a.union(&c.1), b.union(&c.2))
    });
    // Pass 2: chunk j's lefts follow those of chunks before it; its rights, reversed,
    // precede (from the back) those of chunks before it.
    let (dst_left, dst_right) = dst.split_at_mut(mid);
    let mut left_parts = Vec::with_capacity(counts.len());
    let mut right_parts = Vec::with_capacity(counts.len());
    let (mut lrest, mut rrest) = (dst_left, dst_right);
    for (chunk, c) in src.chunks(PARALLEL_THRESHOLD).zip(&counts) {
        let (l, lr) = lrest.split_at_mut(c.0);
        let (rr, r) = rrest.split_at_mut(rrest.len() - (chunk.len() - c.0));
        left_parts.push(l);
        right_parts.push(r);
        (lrest, rrest) = (lr, rr);
    }
    src.par_chunks(PARALLEL_THRESHOLD)
        .zip(left_parts.into_par_iter().zip(right_parts.into_par_iter()))
        .for_each(|(chunk, (l, r))| {
            let right_end = r.as_mut_ptr_range().end;
            // SAFETY: pass 1 counted `l.len()` lefts and `r.len()` rights in this chunk
            // with the same test, so the kernel writes exactly `l` and `r`.
            let (k, _, _) =
                unsafe { partition_on_axis(chunk, l.as_mut_ptr(), right_end, s.axis, p) };
            assert_eq!(k, l.len(), "the two passes of the partition agree");
        });
    (mid, left, right)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn refs(n: usize) -> Vec<PrimRef> {
        (0..n)
            .map(|i| {
                let x = ((i * 7919) % 1013) as f32;
                let y = ((i * 104_729) % 997) as f32 * 0.5;
                let b = Aabb::new(
                    glam::Vec3::new(x, y, 0.0),
                    glam::Vec3::new(x + 1.0, y + 2.0, 1.0),
                );
                PrimRef::new(b, i as u32)
            })
            .collect()
    }

    fn bits(refs: &[PrimRef]) -> Vec<u32> {
        refs.iter()
            .flat_map(|r| r.min.to_array().into_iter().chain(r.max.to_array()))
            .map(f32::to_bits)
            .collect()
    }

    /// A reference's centroid has no subnormal lane whatever its id (the id sits in
    /// the `w` lane of `min` as a subnormal bit pattern; halving it would take a
    /// microcode assist per reference on Intel cores), and its `x, y, z` are the box's
    /// centre, bit for bit, for ids across the whole range.
    #[test]
    fn centroids_carry_no_subnormal_lane() {
        let b = Aabb::new(
            glam::Vec3::new(-3.0, 0.25, 1e-30),
            glam::Vec3::new(5.0, 0.75, 3e-30),
        );
        for id in [
            1u32,
            2,
            69_450,
            1 << 22,
            (1 << 23) - 1,
            1 << 23,
            u32::MAX - 1,
        ] {
            let r = PrimRef::new(b, id);
            assert_eq!(r.id(), id);
            let c = r.centroid();
            let lanes = r.centroid4().to_array();
            assert!(
                lanes.iter().all(|v| !v.is_subnormal()),
                "id {id}: {lanes:?}"
            );
            assert_eq!(
                c.to_array().map(f32::to_bits),
                b.center().to_array().map(f32::to_bits)
            );
        }
    }

    /// The parallel partition writes exactly what the serial loop writes (left in
    /// input order, right reversed) and gathers the same bounds.
    #[test]
    fn parallel_partition_matches_the_serial_one() {
        let src = refs(PARALLEL_NODE * 2 + 123);
        let nb = node_bounds(&src);
        let s = Split {
            axis: 0,
            bin: 13,
            bins: 32,
            cost: 0.0,
        };
        let scale = bin_scale(&nb.centroids, s.bins);
        let mut serial = src.clone();
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        let (m1, l1, r1) =
            pool.install(|| partition(&src, &mut serial, &nb.centroids, s, PARALLEL_NODE));
        let mut parallel = src.clone();
        let (m2, l2, r2) = partition_parallel(&src, &mut parallel, nb.centroids.min, scale, s);
        assert!(m1 > 1000 && m1 < src.len() - 1000, "a real split: {m1}");
        assert_eq!(m1, m2);
        assert_eq!(bits(&serial), bits(&parallel));
        for (a, b) in [(l1, l2), (r1, r2)] {
            assert_eq!(a.min, b.min);
            assert_eq!(a.max, b.max);
        }
        // left in input order, right reversed
        let ids: Vec<u32> = serial.iter().map(PrimRef::id).collect();
        assert!(ids[..m1].windows(2).all(|w| w[0] < w[1]));
        assert!(ids[m1..].windows(2).all(|w| w[0] > w[1]));
    }

    /// Boxes of every size and place on all three axes (a pseudo-random walk).
    fn refs_3d(n: usize) -> Vec<PrimRef> {
        let mut x = 0x2545_f491_u32;
        let mut next = || {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            (x % 10_000) as f32 * 0.01
        };
        (0..n)
            .map(|i| {
                let lo = glam::Vec3::new(next(), next() * 0.5, next() * 2.0);
                let size = glam::Vec3::new(next(), next(), next()) * 0.05;
                PrimRef::new(Aabb::new(lo, lo + size), i as u32)
            })
            .collect()
    }

    fn box_bits(b: &BBox) -> [u32; 6] {
        let (lo, hi) = (b.min.to_array(), b.max.to_array());
        [lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]].map(f32::to_bits)
    }

    /// Two bin sets merged hold exactly what one set fills (odd count: the remainder).
    #[test]
    fn paired_binning_fills_the_same_bins() {
        let src = refs_3d(1001);
        let nb = node_bounds(&src);
        let scale = bin_scale(&nb.centroids, MAX_BINS);
        let mut one = Bins::new();
        one.add_all(&src, nb.centroids.min, scale, MAX_BINS);
        let (mut two, mut other) = (Bins::new(), Bins::new());
        two.add_all_paired(&mut other, &src, nb.centroids.min, scale, MAX_BINS);
        assert_eq!(one.counts, two.counts);
        for a in 0..3 {
            for k in 0..MAX_BINS {
                assert_eq!(box_bits(&one.bounds(a, k)), box_bits(&two.bounds(a, k)));
            }
        }
        assert_eq!((0..MAX_BINS).map(|k| one.count(0, k)).sum::<u32>(), 1001);
        assert!(one.counts.iter().all(|c| c[3] == 0), "lane 3 stays zero");
    }

    /// For every plane of every axis: the children's boxes read off the bins are those
    /// of the references the partition sends each way, the centroid bounds it gathers
    /// are theirs, and the one-axis test agrees with the bins.
    #[test]
    fn children_boxes_from_the_bins_match_the_partition() {
        let src = refs_3d(3000);
        let nb = node_bounds(&src);
        let bins_n = 16;
        let scale = bin_scale(&nb.centroids, bins_n);
        let mut bins = Bins::new();
        bins.add_all(&src, nb.centroids.min, scale, bins_n);
        let mut dst = src.clone();
        let mut real_splits = 0;
        for axis in 0..3 {
            for bin in 1..bins_n {
                let s = Split {
                    axis,
                    bin,
                    bins: bins_n,
                    cost: 0.0,
                };
                let (m, lc, rc) = partition(&src, &mut dst, &nb.centroids, s, PARALLEL_NODE);
                for r in &src {
                    let k = bins_of(r.centroid(), nb.centroids.min, scale, bins_n);
                    assert_eq!(goes_left(r, nb.centroids.min, scale, s), k[axis] < bin);
                }
                if m == 0 || m == src.len() {
                    continue;
                }
                real_splits += 1;
                let union = |r: std::ops::Range<usize>| {
                    r.fold(BBox::EMPTY, |a, k| a.union(&bins.bounds(axis, k)))
                };
                let (l, r) = (node_bounds(&dst[..m]), node_bounds(&dst[m..]));
                assert_eq!(box_bits(&union(0..bin)), box_bits(&l.bounds));
                assert_eq!(box_bits(&union(bin..bins_n)), box_bits(&r.bounds));
                assert_eq!(box_bits(&lc), box_bits(&l.centroids));
                assert_eq!(box_bits(&rc), box_bits(&r.centroids));
            }
        }
        assert!(real_splits > 40, "{real_splits} planes split the set");
    }

    /// The sweep's chosen split carries the children's boxes of that split.
    #[test]
    fn the_sweep_returns_its_sides_boxes() {
        let src = refs_3d(2000);
        let nb = node_bounds(&src);
        let builder = Builder {
            opts: Bvh2BuildOptions::default(),
            block_shift: Some(0),
            sample_from: usize::MAX,
            parallel_from: PARALLEL_NODE,
            pairs: Arena::new(0),
        };
        let c = builder.best_split(&src, &nb).expect("a split");
        let mut dst = src.clone();
        let (m, _, _) = partition(&src, &mut dst, &nb.centroids, c.split, PARALLEL_NODE);
        assert!(m > 0 && m < src.len());
        assert_eq!(box_bits(&c.left), box_bits(&node_bounds(&dst[..m]).bounds));
        assert_eq!(box_bits(&c.right), box_bits(&node_bounds(&dst[m..]).bounds));
    }

    /// The partition against a plain reference: the references [`bins_of`] puts below
    /// the split bin, in input order, then the others in reverse order, and the
    /// centroid bounds of each side folded one by one; for every plane of every axis,
    /// with a NaN, a far and an infinite centroid among the references.
    #[test]
    fn partition_matches_a_plain_reference() {
        let mut src = refs_3d(777);
        let nan = Aabb {
            min: glam::Vec3::splat(f32::NAN),
            max: glam::Vec3::splat(f32::NAN),
        };
        src[5] = PrimRef::new(nan, 5);
        let far = Aabb::new(glam::Vec3::splat(1e30), glam::Vec3::splat(2e30));
        src[6] = PrimRef::new(far, 6);
        let inf = Aabb {
            min: glam::Vec3::splat(f32::INFINITY),
            max: glam::Vec3::splat(f32::INFINITY),
        };
        src[7] = PrimRef::new(inf, 7);
        // The node's bounds from the ordinary references: the others fall outside.
        let nb = node_bounds(&src[8..]);
        let bins_n = 16;
        let scale = bin_scale(&nb.centroids, bins_n);
        let mut dst = vec![PrimRef::new(far, u32::MAX); src.len()];
        for axis in 0..3 {
            for bin in 1..bins_n {
                let s = Split {
                    axis,
                    bin,
                    bins: bins_n,
                    cost: 0.0,
                };
                let left_of = |r: &PrimRef| {
                    bins_of(r.centroid(), nb.centroids.min, scale, bins_n)[axis] < bin
                };
                let mut want: Vec<PrimRef> = src.iter().filter(|r| left_of(r)).copied().collect();
                let m = want.len();
                want.extend(src.iter().rev().filter(|r| !left_of(r)).copied());
                let (got_m, lc, rc) = partition(&src, &mut dst, &nb.centroids, s, PARALLEL_NODE);
                assert_eq!(got_m, m, "axis {axis} bin {bin}");
                assert_eq!(bits(&dst), bits(&want), "axis {axis} bin {bin}");
                let cb = |r: &[PrimRef]| {
                    r.iter().fold(BBox::EMPTY, |mut b, r| {
                        b.grow_point(r.centroid());
                        b
                    })
                };
                assert_eq!(box_bits(&lc), box_bits(&cb(&want[..m])));
                assert_eq!(box_bits(&rc), box_bits(&cb(&want[m..])));
            }
        }
    }

    /// Sampled bins against a plain reference: per axis and bin, the count (times the
    /// weight) and the box fold of exactly the references at positions `i % 16 < 2`,
    /// for lengths that end inside a block, on one block's first reference, and on a
    /// whole block.
    #[test]
    fn sampled_bins_match_a_plain_fold_of_the_sample() {
        let all = refs_3d(3000);
        for len in [3000, 2993, 2977, 2976] {
            let src = &all[..len];
            let nb = node_bounds(src);
            let bins_n = 16;
            let scale = bin_scale(&nb.centroids, bins_n);
            let mut want = vec![[(0u32, BBox::EMPTY); MAX_BINS]; 3];
            let mut sampled = 0;
            for (i, r) in src.iter().enumerate() {
                if i % SAMPLE_BLOCK >= 2 {
                    continue;
                }
                sampled += 1;
                let k = bins_of(r.centroid(), nb.centroids.min, scale, bins_n);
                for a in 0..3 {
                    let (c, b) = &mut want[a][k[a]];
                    *c += SAMPLE_WEIGHT;
                    *b = b.union(&r.bounds());
                }
            }
            let (mut bins, mut other) = (Bins::new(), Bins::new());
            bins.add_sampled(&mut other, src, nb.centroids.min, scale, bins_n);
            bins.weigh(bins_n, SAMPLE_WEIGHT);
            for (a, want_a) in want.iter().enumerate() {
                for (k, (count, bounds)) in want_a.iter().enumerate() {
                    assert_eq!(bins.count(a, k), *count, "len {len} axis {a} bin {k}");
                    assert_eq!(box_bits(&bins.bounds(a, k)), box_bits(bounds));
                }
            }
            let total: u32 = (0..MAX_BINS).map(|k| bins.count(0, k)).sum();
            assert_eq!(total, sampled * SAMPLE_WEIGHT, "len {len}");
        }
    }

    /// The SAH cost of a build tree (interior nodes 1, leaves their started blocks of
    /// `block`, each weighted by its area over the root's).
    fn tree_sah(root: &BuildNode, block: usize) -> f64 {
        let inv = 1.0 / root.area() as f64;
        let mut stack = vec![root];
        let mut cost = 0.0;
        while let Some(n) = stack.pop() {
            let a = n.area() as f64 * inv;
            match n {
                BuildNode::Leaf { count, .. } => {
                    cost += a * (*count as usize).div_ceil(block) as f64
                }
                BuildNode::Interior { children, .. } => {
                    cost += a;
                    stack.extend(children.iter());
                }
            }
        }
        cost
    }

    /// Binning a sample of the large nodes keeps the tree's SAH cost within 1 % of
    /// binning every reference (the README reports the change at 10^6), on the
    /// procedural mesh with the BVH8's options; every primitive is in exactly one leaf
    /// and every node's box holds its children's.
    #[test]
    fn sampled_binning_keeps_the_sah_cost() {
        let tris = crate::bench::BenchMesh::procedural(200_000).triangles;
        let opts = Bvh2BuildOptions {
            max_leaf: 4,
            block_size: 4,
            ..Bvh2BuildOptions::default()
        };
        let (full, _, _) = build_tree_sampling(&tris, opts, usize::MAX);
        let (sampled, ids, _) = build_tree_sampling(&tris, opts, SAMPLED_BINNING);
        let (full, sampled) = (full.unwrap(), sampled.unwrap());
        let (a, b) = (tree_sah(&full, 4), tree_sah(&sampled, 4));
        println!("SAH full {a:.4}, sampled {b:.4}");
        assert!((b - a).abs() <= 0.01 * a, "SAH full {a}, sampled {b}");
        let mut seen = vec![false; tris.v0.len()];
        for &i in &ids {
            assert!(
                !std::mem::replace(&mut seen[i as usize], true),
                "id {i} twice"
            );
        }
        assert!(seen.iter().all(|&s| s));
        // Every box is exact: an interior node's the union of its children's, a leaf's
        // the union of its primitives' (sampled nodes rebuild theirs from below).
        let mut stack: Vec<&BuildNode> = vec![&sampled];
        let vals = |b: &BBox| [b.min.to_array(), b.max.to_array()];
        let mut interiors = 0;
        while let Some(n) = stack.pop() {
            match n {
                BuildNode::Interior { bounds, children } => {
                    interiors += 1;
                    let u = children[0].bbox().union(&children[1].bbox());
                    assert_eq!(vals(bounds), vals(&u));
                    stack.extend(children.iter());
                }
                BuildNode::Leaf {
                    bounds,
                    start,
                    count,
                } => {
                    let u = ids[*start as usize..(start + count) as usize].iter().fold(
                        BBox::EMPTY,
                        |b, &i| {
                            let pb = tris.bounds(i as usize);
                            b.union(&BBox {
                                min: pb.min.into(),
                                max: pb.max.into(),
                            })
                        },
                    );
                    assert_eq!(vals(bounds), vals(&u));
                }
            }
        }
        assert!(interiors > 40_000, "{interiors} interior nodes");
    }

    /// The lane sweep picks the scalar sweep's split (axis, bin, cost bit for bit) and
    /// sides, on nodes of every size from 2 to 3000 references, flat ones included.
    #[test]
    fn lane_sweep_matches_the_scalar_sweep() {
        let all = refs_3d(3000);
        let mut flat = refs_3d(500);
        for r in &mut flat {
            r.min.z = 1.0;
            r.max.z = 1.0;
        }
        let mut nodes: Vec<&[PrimRef]> = (2..40).map(|n| &all[n * 7..n * 8]).collect();
        nodes.extend([&all[..100], &all[100..1100], &all[..], &flat[..]]);
        let mut compared = 0;
        for bs in [1usize, 4] {
            let builder = Builder {
                opts: Bvh2BuildOptions {
                    block_size: bs,
                    ..Bvh2BuildOptions::default()
                },
                block_shift: Some(bs.trailing_zeros()),
                sample_from: usize::MAX,
                parallel_from: PARALLEL_NODE,
                pairs: Arena::new(0),
            };
            for refs in &nodes {
                let nb = node_bounds(refs);
                for bins_n in [4, 7, 16, MAX_BINS] {
                    let scale = bin_scale(&nb.centroids, bins_n);
                    let mut bins = Bins::new();
                    bins.add_all(refs, nb.centroids.min, scale, bins_n);
                    let shift = bs.trailing_zeros();
                    let lanes = builder.sweep_lanes(&bins, bins_n, &nb, shift);
                    let scalar = builder.sweep_scalar(&bins, bins_n, &nb);
                    match (lanes, scalar) {
                        (Some(a), Some(b)) => {
                            assert_eq!(
                                (a.split.axis, a.split.bin, a.split.cost.to_bits()),
                                (b.split.axis, b.split.bin, b.split.cost.to_bits()),
                                "{} refs, {bins_n} bins, block {bs}",
                                refs.len()
                            );
                            assert_eq!(box_bits(&a.left), box_bits(&b.left));
                            assert_eq!(box_bits(&a.right), box_bits(&b.right));
                            compared += 1;
                        }
                        (None, None) => {}
                        _ => panic!(
                            "one sweep found a split, the other none ({} refs)",
                            refs.len()
                        ),
                    }
                }
            }
        }
        assert!(compared > 300, "{compared} splits compared");
    }

    /// The bins' byte offsets are 16 times the bins (`bins_of`, plain `as` casts of the
    /// clamped coordinates) for centroids inside, on and outside the node's grid, NaN
    /// and infinite ones included, and for every bin count.
    #[test]
    fn bin_offsets_are_sixteen_times_the_bins() {
        let src = refs_3d(700);
        let nb = node_bounds(&src);
        let odd = [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, -1e30, 1e30, 0.0];
        let mut cents: Vec<Vec3A> = src.iter().map(PrimRef::centroid).collect();
        cents.extend(odd.iter().map(|&v| Vec3A::new(v, 1.0, -v)));
        cents.push(nb.centroids.min);
        cents.push(nb.centroids.max);
        for bins_n in 2..=MAX_BINS {
            let scale = bin_scale(&nb.centroids, bins_n);
            for &c in &cents {
                let k = bins_of(c, nb.centroids.min, scale, bins_n);
                assert!(k.iter().all(|&k| k < bins_n), "{c:?}: {k:?}");
                let want = k.map(|k| 16 * k as u32);
                assert_eq!(
                    bin_offsets(c, nb.centroids.min, scale, bins_n),
                    want,
                    "{c:?}"
                );
            }
        }
    }

    /// The bins (kept as [`BinBox`]es) against a plain reference: per axis and bin,
    /// the count and the min/max fold of the boxes of the references [`bins_of`] puts
    /// there, bit for bit, serial and paired, for several bin counts.
    #[test]
    fn bins_match_a_plain_fold_of_their_references() {
        let src = refs_3d(1501);
        let nb = node_bounds(&src);
        for bins_n in [2, 5, 16, MAX_BINS] {
            let scale = bin_scale(&nb.centroids, bins_n);
            let mut want = vec![[(0u32, BBox::EMPTY); MAX_BINS]; 3];
            for r in &src {
                let k = bins_of(r.centroid(), nb.centroids.min, scale, bins_n);
                for a in 0..3 {
                    let (c, b) = &mut want[a][k[a]];
                    *c += 1;
                    b.min = b.min.min(r.bounds().min);
                    b.max = b.max.max(r.bounds().max);
                }
            }
            let mut one = Bins::new();
            one.add_all(&src, nb.centroids.min, scale, bins_n);
            let (mut two, mut other) = (Bins::new(), Bins::new());
            two.add_all_paired(&mut other, &src, nb.centroids.min, scale, bins_n);
            for bins in [&one, &two] {
                for (a, want_a) in want.iter().enumerate() {
                    for (k, (count, bounds)) in want_a.iter().enumerate() {
                        assert_eq!(bins.count(a, k), *count, "axis {a} bin {k}");
                        assert_eq!(
                            box_bits(&bins.bounds(a, k)),
                            box_bits(bounds),
                            "axis {a} bin {k} of {bins_n}"
                        );
                    }
                }
            }
            let filled = want[0][..bins_n].iter().filter(|w| w.0 > 0).count();
            assert!(filled == bins_n, "{filled} of {bins_n} bins filled");
        }
    }

    /// Compares two trees node by node: shape, leaf ranges, and boxes equal as numbers
    /// (a zero's sign may follow the grouping of a parallel reduction, which depends on
    /// the thread count); returns the node count.
    fn same_tree(a: &BuildNode, b: &BuildNode) -> usize {
        let vals = |b: &BBox| {
            let (lo, hi) = (b.min.to_array(), b.max.to_array());
            [lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]]
        };
        match (a, b) {
            (
                BuildNode::Leaf {
                    bounds: ba,
                    start: sa,
                    count: ca,
                },
                BuildNode::Leaf {
                    bounds: bb,
                    start: sb,
                    count: cb,
                },
            ) => {
                assert_eq!(vals(ba), vals(bb));
                assert_eq!((sa, ca), (sb, cb));
                1
            }
            (
                BuildNode::Interior {
                    bounds: ba,
                    children: ca,
                },
                BuildNode::Interior {
                    bounds: bb,
                    children: cb,
                },
            ) => {
                assert_eq!(vals(ba), vals(bb));
                1 + same_tree(&ca[0], &cb[0]) + same_tree(&ca[1], &cb[1])
            }
            _ => panic!("a leaf against an interior node"),
        }
    }

    /// The parallel build (nodes of at least [`PARALLEL_NODE`] references sampled, those
    /// of a thread's share partitioned in parallel chunks, subtrees on two and four
    /// threads) builds the 1-thread build's tree, node for node, with the same primitive
    /// order, on the procedural mesh and on a soup of random triangles, for the BVH2's
    /// and the BVH8's options; the BVH8 built over each at every thread count validates.
    #[test]
    fn two_threads_build_the_one_thread_tree() {
        let mut x = 0x1234_5678_u32;
        let mut next = || {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            (x % 100_000) as f32 * 0.001
        };
        let soup: Vec<[glam::Vec3; 3]> = (0..40_000)
            .map(|_| {
                let a = glam::Vec3::new(next(), next(), next() * 0.1);
                [
                    a,
                    a + glam::Vec3::new(next(), 0.0, 0.0) * 0.02,
                    a + glam::Vec3::splat(next() * 0.01),
                ]
            })
            .collect();
        let meshes = [
            crate::bench::BenchMesh::procedural(60_000).triangles,
            crate::accel::Triangles::from_corners(&soup),
        ];
        // 4 threads: nodes down to a quarter of the references partition in parallel
        // (`parallel_partition_from`), at 2 threads only those of at least half.
        let pools = [1, 2, 4].map(|t| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(t)
                .build()
                .unwrap()
        });
        for tris in &meshes {
            for opts in [
                Bvh2BuildOptions::default(),
                // The BVH8's options for triangles (`bvhn::tree::wide_build_options`).
                Bvh2BuildOptions {
                    max_leaf: 4,
                    block_size: 4,
                    ..Bvh2BuildOptions::default()
                },
            ] {
                let [(one, one_ids), more @ ..] = pools
                    .each_ref()
                    .map(|p| p.install(|| build_tree(tris, opts)));
                for (tree, ids) in &more {
                    let nodes = same_tree(one.as_ref().unwrap(), tree.as_ref().unwrap());
                    assert!(nodes > tris.v0.len() / 4, "{nodes} nodes");
                    assert_eq!(&one_ids, ids);
                }
            }
            for p in &pools {
                let bvh = p.install(|| crate::accel::Bvh8::build(tris.clone()));
                bvh.validate().expect("a valid BVH8");
            }
        }
    }

    /// Degenerate input builds without a panic and every primitive lands in exactly
    /// one leaf: NaN and infinite corners, zero-area triangles, and large sets whose
    /// centroids are all equal (they go through the sampled and parallel levels), for
    /// the BVH2's and the BVH8's options.
    #[test]
    fn degenerate_triangles_build_and_keep_every_primitive() {
        use glam::Vec3;
        let tri = |a: Vec3| [a, a + Vec3::X, a + Vec3::Y];
        let mut mixed: Vec<[Vec3; 3]> = (0..50_000)
            .map(|i| tri(Vec3::new((i % 300) as f32, (i / 300) as f32, 0.0)))
            .collect();
        for (i, t) in mixed.iter_mut().enumerate().step_by(7) {
            t[i % 3] = match i % 4 {
                0 => Vec3::NAN,
                1 => Vec3::splat(f32::INFINITY),
                2 => Vec3::new(f32::NEG_INFINITY, 0.0, f32::NAN),
                _ => t[(i + 1) % 3], // zero area
            };
        }
        let same = vec![tri(Vec3::ONE); 40_000];
        let flat = vec![[Vec3::ZERO; 3]; 5];
        for corners in [&mixed, &same, &flat] {
            let tris = crate::accel::Triangles::from_corners(corners);
            let wide = Bvh2BuildOptions {
                max_leaf: 4,
                block_size: 4,
                ..Bvh2BuildOptions::default()
            };
            for opts in [Bvh2BuildOptions::default(), wide] {
                let (tree, ids) = build_tree(&tris, opts);
                let mut seen = vec![false; corners.len()];
                for &id in &ids {
                    assert!(
                        !std::mem::replace(&mut seen[id as usize], true),
                        "{id} twice"
                    );
                }
                assert!(seen.iter().all(|&s| s), "every primitive in a leaf");
                let mut stack: Vec<&BuildNode> = vec![tree.as_ref().expect("a tree")];
                let mut covered = 0;
                while let Some(node) = stack.pop() {
                    match node {
                        BuildNode::Leaf { start, count, .. } => {
                            assert_eq!(*start as usize, covered, "leaves in order");
                            covered += *count as usize;
                        }
                        BuildNode::Interior { children, .. } => {
                            stack.push(&children[1]);
                            stack.push(&children[0]);
                        }
                    }
                }
                assert_eq!(covered, corners.len());
            }
        }
    }

    /// The references' arrays come zeroed, at every size (huge-page advice from 4 MiB;
    /// above 32 MiB over every page they touch).
    #[test]
    fn zeroed_refs_are_zero() {
        for n in [0, 1, 1000, (4 << 20) / 32 + 3, RECYCLE_MIN_BYTES / 32 + 3] {
            let v = zeroed_refs(n);
            assert_eq!(v.len(), n);
            assert!(bits(&v).iter().all(|&b| b == 0), "{n} references");
        }
        for n in [0, 1, 1000, (4 << 20) / 4 + 3, RECYCLE_MIN_BYTES / 4 + 3] {
            let mut v = zeroed_ids(n);
            assert_eq!((v.len(), v.capacity()), (n, n));
            assert!(v.iter().all(|&i| i == 0), "{n} indices");
            // A `Vec` of the global allocator: it grows and frees as one.
            v.push(7);
            assert_eq!(v[n], 7);
        }
    }

    /// A spare reference array becomes an empty array of exactly the asked room
    /// (taken over when large: grown past it, shrunk inside it, or with none), and the
    /// array holds and returns every value written to it, up to its capacity.
    #[test]
    fn spare_refs_become_an_array_of_the_asked_room() {
        #[derive(Clone, Copy, PartialEq, Debug)]
        #[repr(C, align(16))]
        struct Group([u32; 40]);
        let large = RECYCLE_MIN_BYTES / 32 + 5;
        for n in [0, 1000, large] {
            for room in [0, 1, 7, n * 32 / 160 + 1, n * 32 / 160 + 50_000] {
                let mut v = SpareRefs(zeroed_refs(n)).into_vec::<Group>(room);
                assert!(v.is_empty(), "{n} references, room {room}");
                if n >= large && room > 0 {
                    assert_eq!(v.capacity(), room, "{n} references");
                } else {
                    assert!(v.capacity() >= room, "{n} references, room {room}");
                }
                let value = |i: usize| Group(std::array::from_fn(|k| (i * 40 + k) as u32));
                v.extend((0..room).map(value));
                assert!(v.iter().enumerate().all(|(i, g)| *g == value(i)));
            }
        }
    }

    /// The shift gives the started blocks the division gives.
    #[test]
    fn blocks_by_shift_match_the_division() {
        for bs in [1usize, 2, 4, 8] {
            let opts = Bvh2BuildOptions {
                block_size: bs,
                ..Bvh2BuildOptions::default()
            };
            let shifted = Builder {
                opts,
                block_shift: Some(bs.trailing_zeros()),
                sample_from: usize::MAX,
                parallel_from: PARALLEL_NODE,
                pairs: Arena::new(0),
            };
            let divided = Builder {
                opts,
                block_shift: None,
                sample_from: usize::MAX,
                parallel_from: PARALLEL_NODE,
                pairs: Arena::new(0),
            };
            for n in 0..100u32 {
                assert_eq!(shifted.blocks(n), divided.blocks(n));
                assert_eq!(divided.blocks(n), n.div_ceil(bs as u32) as f32);
            }
        }
    }

    /// The id survives the round trip through the spare lane, NaN-pattern ids included.
    #[test]
    fn prim_ref_keeps_its_id() {
        let b = Aabb::new(glam::Vec3::ZERO, glam::Vec3::ONE);
        for id in [0, 1, 0x7fc0_0001, u32::MAX - 1] {
            assert_eq!(PrimRef::new(b, id).id(), id);
        }
    }
}
