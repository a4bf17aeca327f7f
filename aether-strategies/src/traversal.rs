//! A ray's state while it walks a decoded tree ([`crate::wide`]): the
//! fields obvhs's `traverse!` loop reads, with a stack short enough to
//! clear in a few stores.

use glam::{UVec2, Vec3A};

/// The traversal stack of a decoded tree: obvhs's holds 32 groups, which
/// every ray zeroed through a call to `memset` (1 % of a path tracer's
/// instructions); a decoded tree is kept only if it is shallow enough for
/// this one, whose zeroing is a few stores.
#[derive(Clone, Copy, Default)]
pub(crate) struct ShortStack {
    groups: [UVec2; STACK],
    len: usize,
}

/// Groups the short stack holds: a ray keeps at most one group per level
/// above the node it visits.
pub(crate) const STACK: usize = 16;

impl obvhs::faststack::FastStack<UVec2> for ShortStack {
    #[inline(always)]
    fn push(&mut self, v: UVec2) {
        // Never full: decoded trees have at most `STACK` levels.
        debug_assert!(self.len < STACK, "a decoded tree deeper than the stack");
        if let Some(slot) = self.groups.get_mut(self.len) {
            *slot = v;
            self.len += 1;
        }
    }
    #[inline(always)]
    fn pop_fast(&mut self) -> UVec2 {
        self.len = self.len.saturating_sub(1);
        self.groups[self.len]
    }
    #[inline(always)]
    fn pop(&mut self) -> Option<UVec2> {
        (self.len > 0).then(|| self.pop_fast())
    }
    #[inline(always)]
    fn len(&self) -> usize {
        self.len
    }
    #[inline(always)]
    fn is_empty(&self) -> bool {
        self.len == 0
    }
    #[inline(always)]
    fn clear(&mut self) {
        self.len = 0;
    }
}

/// A ray's traversal state, with the fields obvhs's `traverse!` loop reads
/// by these names, as `obvhs::cwbvh::Traversal` has them.
pub(crate) struct Walk {
    pub(crate) stack: ShortStack,
    pub(crate) current_group: UVec2,
    pub(crate) primitive_group: UVec2,
    pub(crate) oct_inv4: u32,
    pub(crate) primitive_id: u32,
    pub(crate) hitmask: u32,
}

impl Walk {
    #[inline(always)]
    pub(crate) fn new(direction: Vec3A) -> Self {
        Walk {
            stack: ShortStack::default(),
            current_group: UVec2::new(0, 0x8000_0000),
            primitive_group: UVec2::ZERO,
            oct_inv4: octant_inv4(direction),
            primitive_id: 0,
            hitmask: 0,
        }
    }
}

/// The ray's octant as obvhs's traversal encodes it (its own function is
/// private): per axis, a bit set where the direction is not negative,
/// repeated in each byte.
#[inline(always)]
pub(crate) fn octant_inv4(direction: Vec3A) -> u32 {
    let bit = |negative: bool, b: u32| if negative { 0 } else { b };
    bit(direction.x < 0.0, 0x0404_0404)
        | bit(direction.y < 0.0, 0x0202_0202)
        | bit(direction.z < 0.0, 0x0101_0101)
}
