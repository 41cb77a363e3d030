//! Live components by handle, found without a lock on every call.
//!
//! The handle given to the importer encodes a slot of a table and the slot's generation, not
//! an address: a handle that is not live (NULL, freed, foreign) is refused before anything is
//! dereferenced, and a stale handle never reaches a component created later in the same slot,
//! so a double fmi2FreeInstance cannot corrupt memory. Adding and removing take a lock; a
//! lookup reads four atomics. The table grows by chunks that live as long as the library.

use super::guard::Component;
use std::sync::atomic::{AtomicPtr, AtomicUsize, Ordering};
use std::sync::Mutex;

const CHUNK_BITS: u32 = 10;
const SLOT_BITS: u32 = 20;
const CHUNK: usize = 1 << CHUNK_BITS;
const CHUNKS: usize = 1 << (SLOT_BITS - CHUNK_BITS);
/// Most components live at once.
pub const CAPACITY: usize = 1 << SLOT_BITS;
const SLOT_MASK: usize = CAPACITY - 1;
/// Handles look like 16-byte-aligned addresses to importers that print them.
const ALIGN_BITS: u32 = 4;
const GENERATIONS: usize = usize::MAX >> (SLOT_BITS + ALIGN_BITS);

struct Slot {
    /// The handle last issued for this slot (0: never used).
    handle: AtomicUsize,
    /// Its component while live, else null.
    component: AtomicPtr<Component>,
}

type Chunk = [Slot; CHUNK];

static CHUNK_TABLE: [AtomicPtr<Chunk>; CHUNKS] = [const { AtomicPtr::new(std::ptr::null_mut()) }; CHUNKS];

/// Slots free for reuse, and the first never used.
struct Free {
    released: Vec<usize>,
    fresh: usize,
}

static FREE: Mutex<Free> = Mutex::new(Free {
    released: Vec::new(),
    fresh: 0,
});

impl Free {
    /// A slot for a new component: a released one first, else a fresh one below `capacity`.
    fn take(&mut self, capacity: usize) -> Option<usize> {
        self.released.pop().or_else(|| {
            (self.fresh < capacity).then(|| {
                self.fresh += 1;
                self.fresh - 1
            })
        })
    }
}

fn free_list() -> std::sync::MutexGuard<'static, Free> {
    // Each update under the lock is a single push, pop or increment: never half done.
    FREE.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

fn slot(index: usize) -> Option<&'static Slot> {
    let chunk = CHUNK_TABLE[index >> CHUNK_BITS].load(Ordering::Acquire);
    // SAFETY: a non-null chunk pointer was stored by `insert` from `Box::leak` and is never
    // freed or replaced.
    let chunk = unsafe { chunk.as_ref()? };
    Some(&chunk[index & (CHUNK - 1)])
}

fn encode(generation: usize, index: usize) -> usize {
    ((generation << SLOT_BITS) | index) << ALIGN_BITS
}

/// (generation, slot index) of a handle that could have been issued, else None.
fn decode(handle: usize) -> Option<(usize, usize)> {
    if handle & ((1 << ALIGN_BITS) - 1) != 0 {
        return None;
    }
    let v = handle >> ALIGN_BITS;
    let generation = v >> SLOT_BITS;
    (generation != 0).then_some((generation, v & SLOT_MASK))
}

/// Stores `component` and returns its handle (never 0); gives it back if `CAPACITY`
/// components are live.
pub fn insert(component: Box<Component>) -> Result<usize, Box<Component>> {
    let mut free = free_list();
    let Some(index) = free.take(CAPACITY) else {
        return Err(component);
    };
    let table = &CHUNK_TABLE[index >> CHUNK_BITS];
    let mut chunk = table.load(Ordering::Acquire);
    if chunk.is_null() {
        let fresh: Box<Chunk> = Box::new(std::array::from_fn(|_| Slot {
            handle: AtomicUsize::new(0),
            component: AtomicPtr::new(std::ptr::null_mut()),
        }));
        chunk = Box::leak(fresh);
        table.store(chunk, Ordering::Release);
    }
    // SAFETY: non-null, from `Box::leak` (here or by an earlier insert, under the same lock),
    // never freed or replaced.
    let slot = unsafe { &(*chunk)[index & (CHUNK - 1)] };
    let previous = decode(slot.handle.load(Ordering::Relaxed)).map_or(0, |(generation, _)| generation);
    let generation = if previous >= GENERATIONS { 1 } else { previous + 1 };
    let handle = encode(generation, index);
    // The new handle first: a lookup of the slot's previous handle that sees the new
    // component then sees the new handle too (see `get`).
    slot.handle.store(handle, Ordering::Release);
    slot.component.store(Box::into_raw(component), Ordering::Release);
    Ok(handle)
}

/// The live component of `handle`, if any.
#[inline]
pub fn get(handle: usize) -> Option<*mut Component> {
    let (_, index) = decode(handle)?;
    let slot = slot(index)?;
    if slot.handle.load(Ordering::Acquire) != handle {
        return None;
    }
    let component = slot.component.load(Ordering::Acquire);
    // Checked again after the component: a stale handle racing with the slot's reuse by
    // another thread would otherwise pair with the new component.
    if component.is_null() || slot.handle.load(Ordering::Acquire) != handle {
        return None;
    }
    Some(component)
}

/// Takes the component of `handle` out of the table, if it is live.
pub fn remove(handle: usize) -> Option<Box<Component>> {
    let mut free = free_list();
    let (_, index) = decode(handle)?;
    let slot = slot(index)?;
    if slot.handle.load(Ordering::Acquire) != handle {
        return None;
    }
    let component = slot.component.swap(std::ptr::null_mut(), Ordering::AcqRel);
    if component.is_null() {
        return None;
    }
    free.released.push(index);
    // SAFETY: the pointer was stored by `insert` from `Box::into_raw` and swapped out of the
    // table just now, under the lock: this is its only owner.
    Some(unsafe { Box::from_raw(component) })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn handles_that_were_never_issued_decode_to_nothing_live() {
        for h in [0, 1, 8, 0x10, 0xdead_beef, usize::MAX, usize::MAX & !0xf, 1 << 40] {
            assert!(get(h).is_none(), "{h:#x}");
        }
        assert_eq!(decode(encode(3, 5)), Some((3, 5)));
        assert_eq!(decode(encode(GENERATIONS, SLOT_MASK)), Some((GENERATIONS, SLOT_MASK)));
    }

    #[test]
    fn slots_run_out_at_the_capacity_and_released_ones_come_back() {
        let mut free = Free {
            released: Vec::new(),
            fresh: 0,
        };
        assert_eq!([free.take(2), free.take(2), free.take(2)], [Some(0), Some(1), None]);
        free.released.push(0);
        assert_eq!([free.take(2), free.take(2)], [Some(0), None]);
    }
}
