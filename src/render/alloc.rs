//! Buffers allocated without aborting: a render that does not fit in
//! memory gets a clear error, not the allocator's abort.

/// `n` copies of `value`, or an error where the memory is not there (not
/// an abort, as `vec!` gives).
pub fn try_filled<T: Clone>(
    n: usize,
    value: T,
) -> Result<Vec<T>, std::collections::TryReserveError> {
    let mut v = Vec::new();
    v.try_reserve_exact(n)?;
    v.resize(n, value);
    Ok(v)
}

/// Whether `bytes` can be reserved now: a probe before a render commits
/// to its buffers (the reservation is released at once).
pub fn can_reserve(bytes: u64) -> bool {
    usize::try_from(bytes)
        .ok()
        .is_some_and(|b| Vec::<u8>::new().try_reserve_exact(b).is_ok())
}
