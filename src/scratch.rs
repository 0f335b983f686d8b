//! Static scratch for code behind `&self` interfaces (the [`crate::matcher::Matcher`]
//! implementations): a fixed set of slots, each a buffer and a claim flag, so that large
//! working buffers live in a `static` instead of on the stack and the matchers stay
//! `Send + Sync`.
//!
//! [`claim`] takes the first free slot and gives it back when the returned guard is dropped;
//! when every slot is in use it waits (spins) for one, so `N` slots run at most `N` users at
//! a time and never fail. A user must not claim a second slot of the same pool while it
//! holds one (nothing in the core does).

use core::cell::UnsafeCell;
use core::ops::{Deref, DerefMut};
use core::sync::atomic::{AtomicBool, Ordering};

/// Slots of each static scratch pool: one on a bare-metal target (one thread), eight on a
/// host, where a thread pool may call a matcher from several threads at once (more callers
/// wait for a free slot).
pub const POOL_SLOTS: usize = if cfg!(target_os = "none") { 1 } else { 8 };

/// One buffer and its claim flag.
pub struct Slot<T> {
    busy: AtomicBool,
    value: UnsafeCell<T>,
}

// Safety: the value is reached only through a `Claim`, which exists for at most one thread
// at a time (the `busy` flag is taken with an acquire compare-exchange and released with a
// release store), so sharing a `Slot` between threads shares no unsynchronized access.
unsafe impl<T: Send> Sync for Slot<T> {}

impl<T> Slot<T> {
    /// A free slot holding `value` (usable in a `static` initializer).
    pub const fn new(value: T) -> Self {
        Self {
            busy: AtomicBool::new(false),
            value: UnsafeCell::new(value),
        }
    }
}

/// Exclusive use of one slot's buffer until dropped.
pub struct Claim<'a, T> {
    slot: &'a Slot<T>,
}

impl<T> Deref for Claim<'_, T> {
    type Target = T;
    fn deref(&self) -> &T {
        // Safety: this claim holds the slot's flag, so no other reference to the value exists.
        unsafe { &*self.slot.value.get() }
    }
}

impl<T> DerefMut for Claim<'_, T> {
    fn deref_mut(&mut self) -> &mut T {
        // Safety: as in `deref`; `&mut self` makes this the only use of the claim.
        unsafe { &mut *self.slot.value.get() }
    }
}

impl<T> Drop for Claim<'_, T> {
    fn drop(&mut self) {
        self.slot.busy.store(false, Ordering::Release);
    }
}

/// Claims a free slot of `slots`, waiting for one when all are in use; `None` only for an
/// empty pool.
pub fn claim<T>(slots: &[Slot<T>]) -> Option<Claim<'_, T>> {
    if slots.is_empty() {
        return None;
    }
    loop {
        for slot in slots {
            if slot
                .busy
                .compare_exchange(false, true, Ordering::Acquire, Ordering::Relaxed)
                .is_ok()
            {
                return Some(Claim { slot });
            }
        }
        core::hint::spin_loop();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn claims_are_exclusive_and_released() {
        let pool = [Slot::new(0u32), Slot::new(0u32)];
        let mut a = claim(&pool).unwrap();
        let mut b = claim(&pool).unwrap();
        *a = 1;
        *b = 2;
        assert!(!core::ptr::eq(&*a, &*b));
        drop(a);
        let c = claim(&pool).unwrap();
        assert_eq!(*c, 1, "the released slot is claimed again");
        drop((b, c));
        assert!(claim::<u32>(&[]).is_none());
    }
}
