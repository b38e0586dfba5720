//! Borrowing the f32 data of candle CPU tensors in place, for the host-side steps (optimiser,
//! custom ops) that would otherwise copy it out through `to_vec`.

use candle_core::{CpuStorage, Layout, Result, Storage, Tensor, bail};

/// The contiguous f32 data of `storage` under `layout`.
pub(crate) fn contiguous_f32<'a>(storage: &'a CpuStorage, layout: &Layout) -> Result<&'a [f32]> {
    match (storage, layout.contiguous_offsets()) {
        (CpuStorage::F32(data), Some((start, end))) => Ok(&data[start..end]),
        _ => bail!("expected a contiguous f32 CPU tensor (layout {layout:?})"),
    }
}

/// Runs `f` on the contiguous f32 data of `t`, without copying it.
pub(crate) fn with_f32<R>(t: &Tensor, f: impl FnOnce(&[f32]) -> R) -> Result<R> {
    let (storage, layout) = t.storage_and_layout();
    let Storage::Cpu(cpu) = &*storage else { bail!("expected a CPU tensor") };
    Ok(f(contiguous_f32(cpu, layout)?))
}
