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

/// `n` zeroed `[f32; N]`, or an error where the memory is not there. The
/// zeros come from the allocator's zeroed memory (`vec!` of zeros), whose
/// pages the kernel maps only when first written: a layer that only part
/// of the image writes (the ground's splats, by day) holds only that
/// part. The reservation first asks whether the memory is there, as
/// [`try_filled`] does; `vec!` itself would abort.
pub fn try_zeroed<const N: usize>(
    n: usize,
) -> Result<Vec<[f32; N]>, std::collections::TryReserveError> {
    Vec::<[f32; N]>::new().try_reserve_exact(n)?;
    Ok(vec![[0.0; N]; n])
}

/// Whether `bytes` can be reserved now: a probe before a render commits
/// to its buffers (the reservation is released at once).
pub fn can_reserve(bytes: u64) -> bool {
    usize::try_from(bytes)
        .ok()
        .is_some_and(|b| Vec::<u8>::new().try_reserve_exact(b).is_ok())
}
