//! Runtime CPU dispatch for the hot loops (warps, blur, morphology, the renderer's blend).
//!
//! vt-core is built for baseline x86-64 (SSE2), where the compiler vectorises 128 bits wide.
//! [`dispatch`] runs a [`Kernel`] through `pulp`'s `Arch::dispatch`, which, on a CPU with
//! AVX-512 (x86-64-v4: F, BW, CD, DQ, VL) or else AVX2 and FMA (x86-64-v3), detected once at
//! run time, calls it from a function compiled with those features, so the kernel's body (and
//! every `#[inline(always)]` function it calls) is vectorised 512 or 256 bits wide; elsewhere it
//! runs as is. OpenCV does the same (it picks AVX2 or AVX-512 kernels at run time). AVX-512
//! took the renderer's moving-viewpoint frame at 1280x720 from 17.2 to 13.2 ms of CPU (the
//! same bytes). The `unsafe` of calling a `#[target_feature]` function lives in `pulp`, behind
//! its feature check; vt-core keeps `unsafe_code` denied.
//!
//! A kernel is a struct (its inputs) with an `#[inline(always)]` [`Kernel::run`], not a closure:
//! a closure's body is a function of its own that the compiler may leave un-inlined, and then
//! compiled for the baseline only.
//!
//! Results are identical on every path: Rust never contracts `a * b + c` into a fused
//! multiply-add on its own, and every operation used (IEEE `+ - * /`, conversions, integer
//! arithmetic) is exactly specified, so only the speed depends on the CPU.

/// A hot loop run by [`dispatch`]. Implementations mark `run` `#[inline(always)]`, and the
/// functions it calls too, or they are compiled for the baseline only.
pub(crate) trait Kernel {
    /// What the loop returns.
    type Output;
    /// The loop.
    fn run(self) -> Self::Output;
}

struct Op<K>(K);

impl<K: Kernel> pulp::WithSimd for Op<K> {
    type Output = K::Output;

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _simd: S) -> K::Output {
        self.0.run()
    }
}

/// Runs `k`, compiled for the best instruction set this CPU has (see the module doc).
#[inline]
pub(crate) fn dispatch<K: Kernel>(k: K) -> K::Output {
    pulp::Arch::new().dispatch(Op(k))
}
