//! Sampling a 5-vertex path, building all its BDPT candidates and
//! combining them allocates nothing in steady state.
// A counting global allocator cannot be written without `unsafe`; it only
// forwards to the system allocator.
#![allow(unsafe_code)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicUsize, Ordering};

use aether_core::testing::{BidirectionalFixture, TestScene, TestVertex};
use aether_core::{Heuristic, Pcg32, RandomSequence, combine};
use smallvec::SmallVec;

struct Counting;

static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

thread_local! {
    static COUNTING: Cell<bool> = const { Cell::new(false) };
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if COUNTING.with(Cell::get) {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        }
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if COUNTING.with(Cell::get) {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        }
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// One sample: a camera and a light subpath, every (s, t) candidate of
/// length 5 and their MIS weights. Returns the sum of the weights.
fn one_sample<'a>(
    fixture: &'a BidirectionalFixture<'_>,
    rng: &mut Pcg32,
    candidates: &mut SmallVec<[RandomSequence<'a, TestVertex>; 8]>,
) -> f64 {
    fixture.sample_candidates(5, rng, candidates);
    combine(candidates, Heuristic::POWER).iter().sum()
}

#[test]
fn steady_state_sampling_and_combine_allocate_nothing() {
    let scene = TestScene::open_box();
    let fixture = BidirectionalFixture::new(&scene);
    let mut rng = Pcg32::new(1, 1);
    let mut candidates = SmallVec::new();
    for _ in 0..100 {
        one_sample(&fixture, &mut rng, &mut candidates);
    }
    let mut combined = 0;
    COUNTING.with(|c| c.set(true));
    for _ in 0..10_000 {
        let total = one_sample(&fixture, &mut rng, &mut candidates);
        combined += usize::from(total > 0.0);
    }
    COUNTING.with(|c| c.set(false));
    let allocations = ALLOCATIONS.load(Ordering::Relaxed);
    println!(
        "{combined} of 10000 samples had a complete 5-vertex candidate; {allocations} allocations"
    );
    assert!(combined > 100, "too few complete paths to mean anything");
    assert_eq!(allocations, 0);
}
