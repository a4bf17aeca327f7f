//! Heap buffers kept for the next sample. Paths live in inline buffers
//! sized for the usual depth; the few that outgrow them (a long path under
//! Russian roulette, a bidirectional technique list past its inline
//! length) take a buffer that an earlier sample gave back to this thread,
//! and give it back when dropped, so that a render allocates while its
//! threads warm up and then no more.
//!
//! Buffers are pooled by type, so a type that borrows (a slot of a
//! sequence borrows its strategy) names its `'static` twin, which has the
//! same layout; an emptied buffer changes between the two without
//! allocating.

use std::any::{Any, TypeId};
use std::cell::RefCell;
use std::ops::{Deref, DerefMut};

use smallvec::{Array, SmallVec};

/// A type whose heap buffers a thread keeps for reuse.
pub trait Recycle: Sized {
    /// `Self` with every lifetime `'static`: the same layout, and the
    /// name of the pool its buffers go to.
    type Static: 'static;
}

impl<T: Recycle> Recycle for Option<T> {
    type Static = Option<T::Static>;
}

/// Plain values that borrow nothing are their own twins.
macro_rules! own_twin {
    ($($t:ty),*) => { $(impl Recycle for $t { type Static = $t; })* };
}
own_twin!(f32, f64, u32, u64, usize, glam::Vec3, glam::DVec3);

/// Buffers kept per type and thread: more than the spilled lists any
/// integrator holds at once, fewer than would hold memory for long.
const KEPT: usize = 32;

type Pools = Vec<(TypeId, Box<dyn Any>)>;

thread_local! {
    static POOLS: RefCell<Pools> = const { RefCell::new(Vec::new()) };
}

/// An emptied buffer of `T` as a buffer of `U`. When the two have one
/// layout, the standard library collects a vector's own iterator into the
/// same allocation (a test checks that no allocation happens); otherwise
/// the buffer is freed and an unallocated one returned.
fn recast<T, U>(mut buffer: Vec<T>) -> Vec<U> {
    buffer.clear();
    buffer
        .into_iter()
        .map(|_| -> U { unreachable!() })
        .collect()
}

fn pool<U: 'static>(pools: &mut Pools) -> &mut Vec<Vec<U>> {
    let id = TypeId::of::<Vec<U>>();
    let i = match pools.iter().position(|(t, _)| *t == id) {
        Some(i) => i,
        None => {
            pools.push((id, Box::new(Vec::<Vec<U>>::new())));
            pools.len() - 1
        }
    };
    pools[i]
        .1
        .downcast_mut()
        .unwrap_or_else(|| unreachable!("a pool is filed under its own type"))
}

/// An empty buffer of at least `capacity`, from this thread's pool when it
/// has one.
fn take<T: Recycle>(capacity: usize) -> Vec<T> {
    // A thread being torn down has no pool left: allocate.
    let kept = POOLS
        .try_with(|p| pool::<T::Static>(&mut p.borrow_mut()).pop())
        .ok()
        .flatten();
    let mut buffer: Vec<T> = kept.map_or_else(Vec::new, recast);
    buffer.reserve(capacity);
    buffer
}

/// Gives `buffer`'s allocation back to this thread's pool.
fn give<T: Recycle>(buffer: Vec<T>) {
    if buffer.capacity() == 0 {
        return;
    }
    let buffer: Vec<T::Static> = recast(buffer);
    let _ = POOLS.try_with(|p| {
        let mut pools = p.borrow_mut();
        let kept = pool::<T::Static>(&mut pools);
        if kept.len() < KEPT {
            kept.push(buffer);
        }
    });
}

/// A [`SmallVec`] whose growth past its inline buffer takes a pooled heap
/// buffer, given back when it is dropped. Reads and in-place changes go
/// through [`Deref`]; grow it with its own [`push`](Self::push),
/// [`extend`](Self::extend) and [`extend_from_slice`](Self::extend_from_slice)
/// (the `SmallVec` ones would allocate a fresh buffer, which is freed).
pub struct Pooled<A: Array>
where
    A::Item: Recycle,
{
    items: SmallVec<A>,
}

impl<A: Array> Pooled<A>
where
    A::Item: Recycle,
{
    /// An empty list, inline.
    #[must_use]
    pub fn new() -> Self {
        Pooled {
            items: SmallVec::new(),
        }
    }

    /// Makes room for `additional` more items: a pooled buffer when the
    /// inline one is too small; a heap buffer that is too small grows in
    /// place, and goes back to the pool the larger.
    #[inline]
    pub fn reserve(&mut self, additional: usize) {
        let needed = self.items.len() + additional;
        if needed > self.items.capacity() {
            self.grow(needed);
        }
    }

    /// Moves the items to a pooled buffer of at least `needed`: kept out of
    /// line, so that the check that almost always passes inlines alone.
    #[cold]
    #[inline(never)]
    fn grow(&mut self, needed: usize) {
        if self.items.spilled() {
            self.items.reserve(needed - self.items.len());
            return;
        }
        let mut buffer = take::<A::Item>(needed.max(2 * A::size()));
        buffer.extend(self.items.drain(..));
        self.items = SmallVec::from_vec(buffer);
    }

    /// Appends `item`. Always inlined: a list of techniques is filled one
    /// push at a time in the inner loop. Only a full inline buffer needs
    /// the pool (SmallVec grows a full heap one itself), which is one
    /// comparison: inline, the length is where a heap capacity would be.
    #[inline(always)]
    pub fn push(&mut self, item: A::Item) {
        if !self.items.spilled() && self.items.len() == A::size() {
            self.grow(A::size() + 1);
        }
        self.items.push(item);
    }

    /// Appends every item of `items`. Room for as many as the iterator
    /// promises comes from the pool; one that yields more than it promised
    /// grows a fresh buffer, which goes to the pool when dropped.
    #[inline]
    pub fn extend(&mut self, items: impl IntoIterator<Item = A::Item>) {
        let items = items.into_iter();
        self.reserve(items.size_hint().0);
        self.items.extend(items);
    }

    /// Appends a copy of `items`.
    #[inline]
    pub fn extend_from_slice(&mut self, items: &[A::Item])
    where
        A::Item: Copy,
    {
        self.reserve(items.len());
        self.items.extend_from_slice(items);
    }
}

impl<A: Array> Default for Pooled<A>
where
    A::Item: Recycle,
{
    fn default() -> Self {
        Self::new()
    }
}

impl<A: Array> Clone for Pooled<A>
where
    A::Item: Recycle + Clone,
{
    fn clone(&self) -> Self {
        if !self.items.spilled() {
            return Pooled {
                items: self.items.clone(),
            };
        }
        let mut copy = Pooled::new();
        copy.extend(self.items.iter().cloned());
        copy
    }
}

impl<A: Array> Drop for Pooled<A>
where
    A::Item: Recycle,
{
    #[inline]
    fn drop(&mut self) {
        if self.items.spilled() {
            give(std::mem::take(&mut self.items).into_vec());
        }
    }
}

impl<A: Array> Deref for Pooled<A>
where
    A::Item: Recycle,
{
    type Target = SmallVec<A>;
    fn deref(&self) -> &SmallVec<A> {
        &self.items
    }
}

impl<A: Array> DerefMut for Pooled<A>
where
    A::Item: Recycle,
{
    fn deref_mut(&mut self) -> &mut SmallVec<A> {
        &mut self.items
    }
}

impl<'a, A: Array> IntoIterator for &'a Pooled<A>
where
    A::Item: Recycle,
{
    type Item = &'a A::Item;
    type IntoIter = std::slice::Iter<'a, A::Item>;
    fn into_iter(self) -> Self::IntoIter {
        self.items.iter()
    }
}

impl<A: Array> std::fmt::Debug for Pooled<A>
where
    A::Item: Recycle + std::fmt::Debug,
{
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        self.items.fmt(f)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    struct Borrowing<'a>(&'a str, u64);
    impl Recycle for Borrowing<'_> {
        type Static = Borrowing<'static>;
    }

    #[test]
    fn a_borrowing_buffer_becomes_its_static_twin_in_place() {
        let text = String::from("strategy");
        let mut buffer = Vec::with_capacity(40);
        buffer.push(Borrowing(&text, 1));
        assert_eq!((buffer[0].0, buffer[0].1), ("strategy", 1));
        let (at, capacity) = (buffer.as_ptr() as usize, buffer.capacity());
        let twin: Vec<Borrowing<'static>> = recast(buffer);
        assert_eq!(twin.as_ptr() as usize, at);
        assert_eq!(twin.capacity(), capacity);
        assert!(twin.is_empty());
    }

    #[test]
    fn a_spilled_list_gives_its_buffer_to_the_next_one() {
        let mut first = Pooled::<[u64; 4]>::new();
        first.extend(0..100);
        assert!(first.spilled());
        let at = first.as_ptr() as usize;
        drop(first);
        let mut second = Pooled::<[u64; 4]>::new();
        second.extend_from_slice(&[1, 2, 3, 4, 5]);
        assert_eq!(second.as_ptr() as usize, at, "the buffer was reused");
        assert_eq!(&second[..], &[1, 2, 3, 4, 5]);
        let copy = second.clone();
        assert_eq!(&copy[..], &second[..]);
        assert_ne!(copy.as_ptr(), second.as_ptr());
    }

    #[test]
    fn a_list_within_its_inline_buffer_takes_nothing() {
        let mut short = Pooled::<[u64; 4]>::new();
        short.extend(0..4);
        assert!(!short.spilled());
    }
}
