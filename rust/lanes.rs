//! Eight f32 lanes for the rasteriser's visibility scan: two rows of four
//! samples tested at once.
//!
//! [`Lanes8`] has two implementations that give the same bits: [`Pair4`],
//! two `wide` four-lane vectors (any target), and [`Avx8`], one AVX register
//! (x86-64, used only inside `raster`'s AVX2 passes, chosen at run time).
//! Every operation is the IEEE operation lane by lane, and Rust never fuses
//! a multiply and an add, so the two agree bit for bit. `wide`'s own f32x8
//! cannot serve the AVX2 pass: it fixes its layout when the crate is
//! compiled, for the baseline target, so it would be two SSE halves there too.
//!
//! Masks are lanes whose bits are all ones (true) or all zeros, as SIMD
//! comparisons give them; u32 values travel in lanes as their bits.
//!
//! `with_avx2!` compiles a hot pass twice, for the baseline target and for
//! AVX2, and picks one at run time: `raster`'s passes and `synthesis`'s
//! direct sums (whose plain loops LLVM vectorises eight lanes wide there).
//! Tests compare the two builds through `tests::both_builds`.

use std::ops::{Add, BitAnd, Mul, Sub};

use wide::{f32x4, u32x4};

/// Whether tests hold the dispatched passes to their baseline build
/// ([`tests::both_builds`]).
#[cfg(test)]
static BASELINE_ONLY: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

#[inline(always)]
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
pub(crate) fn baseline_only() -> bool {
    #[cfg(test)]
    return BASELINE_ONLY.load(std::sync::atomic::Ordering::Relaxed);
    #[cfg(not(test))]
    false
}

/// A hot pass compiled twice: for the baseline target and, chosen at run
/// time where the CPU has it, for AVX2. Rust never contracts a multiply and
/// an add into an FMA, so both run the same IEEE operations and give the
/// same bits; AVX2 code is only encoded better (three-operand VEX
/// instructions, eight-lane vectors, fewer register copies).
macro_rules! with_avx2 {
    ($(#[$doc:meta])* fn $name:ident($($arg:ident: $ty:ty),*) => $avx2:expr, $baseline:expr) => {
        $(#[$doc])*
        fn $name($($arg: $ty),*) {
            #[cfg(target_arch = "x86_64")]
            if std::arch::is_x86_feature_detected!("avx2") && !$crate::lanes::baseline_only() {
                #[target_feature(enable = "avx2")]
                fn avx2($($arg: $ty),*) {
                    $avx2($($arg),*)
                }
                // SAFETY: the CPU has AVX2 (detected just above).
                return unsafe { avx2($($arg),*) };
            }
            $baseline($($arg),*)
        }
    };
}
pub(crate) use with_avx2;

/// Lanes per half: the samples of one row a test covers.
pub(crate) const HALF: usize = 4;

/// Eight f32 lanes in two halves: lanes `0..HALF` (a test's upper row of
/// samples) and `HALF..8` (its lower row).
pub(crate) trait Lanes8: Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + BitAnd<Output = Self> {
    fn splat(v: f32) -> Self;
    /// `upper` in the first half's lanes, `lower` in the second's.
    fn halves(upper: f32, lower: f32) -> Self;
    fn new(values: [f32; 8]) -> Self;
    /// Mask of `self >= other`.
    fn simd_ge(self, other: Self) -> Self;
    fn simd_gt(self, other: Self) -> Self;
    fn simd_le(self, other: Self) -> Self;
    /// With `self` a mask: `if_true` where it is set, `if_false` elsewhere.
    fn select(self, if_true: Self, if_false: Self) -> Self;
    /// The first half from `upper`, the second from `lower`.
    fn load(upper: &[f32; HALF], lower: &[f32; HALF]) -> Self;
    /// Inverse of [`load`](Self::load).
    fn store(self, upper: &mut [f32; HALF], lower: &mut [f32; HALF]);
    /// [`load`](Self::load) of u32 values, as their bits.
    fn load_bits(upper: &[u32; HALF], lower: &[u32; HALF]) -> Self;
    /// [`store`](Self::store) of u32 values, as their bits.
    fn store_bits(self, upper: &mut [u32; HALF], lower: &mut [u32; HALF]);
    /// All lanes holding the bits of `v`.
    fn splat_bits(v: u32) -> Self;
}

/// Two `wide` four-lane vectors: any target.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Pair4([f32x4; 2]);

impl Pair4 {
    #[inline(always)]
    fn map2(self, other: Self, f: impl Fn(f32x4, f32x4) -> f32x4) -> Self {
        Self([f(self.0[0], other.0[0]), f(self.0[1], other.0[1])])
    }
}

macro_rules! pair4_op {
    ($trait:ident, $method:ident, $op:tt) => {
        impl $trait for Pair4 {
            type Output = Self;
            #[inline(always)]
            fn $method(self, other: Self) -> Self {
                self.map2(other, |a, b| a $op b)
            }
        }
    };
}
pair4_op!(Add, add, +);
pair4_op!(Sub, sub, -);
pair4_op!(Mul, mul, *);
pair4_op!(BitAnd, bitand, &);

impl Lanes8 for Pair4 {
    #[inline(always)]
    fn splat(v: f32) -> Self {
        Self([f32x4::splat(v); 2])
    }

    #[inline(always)]
    fn halves(upper: f32, lower: f32) -> Self {
        Self([f32x4::splat(upper), f32x4::splat(lower)])
    }

    #[inline(always)]
    fn new(values: [f32; 8]) -> Self {
        Self([f32x4::new([values[0], values[1], values[2], values[3]]), f32x4::new([values[4], values[5], values[6], values[7]])])
    }

    #[inline(always)]
    fn simd_ge(self, other: Self) -> Self {
        self.map2(other, |a, b| a.simd_ge(b))
    }

    #[inline(always)]
    fn simd_gt(self, other: Self) -> Self {
        self.map2(other, |a, b| a.simd_gt(b))
    }

    #[inline(always)]
    fn simd_le(self, other: Self) -> Self {
        self.map2(other, |a, b| a.simd_le(b))
    }

    #[inline(always)]
    fn select(self, if_true: Self, if_false: Self) -> Self {
        Self([0, 1].map(|h| self.0[h].bitselect(if_true.0[h], if_false.0[h])))
    }

    #[inline(always)]
    fn load(upper: &[f32; HALF], lower: &[f32; HALF]) -> Self {
        Self([f32x4::new(*upper), f32x4::new(*lower)])
    }

    #[inline(always)]
    fn store(self, upper: &mut [f32; HALF], lower: &mut [f32; HALF]) {
        (*upper, *lower) = (self.0[0].to_array(), self.0[1].to_array());
    }

    #[inline(always)]
    fn load_bits(upper: &[u32; HALF], lower: &[u32; HALF]) -> Self {
        Self([*upper, *lower].map(|half| wide::bytemuck::cast(u32x4::new(half))))
    }

    #[inline(always)]
    fn store_bits(self, upper: &mut [u32; HALF], lower: &mut [u32; HALF]) {
        let [a, b] = self.0.map(|half| wide::bytemuck::cast::<f32x4, u32x4>(half).to_array());
        (*upper, *lower) = (a, b);
    }

    #[inline(always)]
    fn splat_bits(v: u32) -> Self {
        Self::splat(f32::from_bits(v))
    }
}

#[cfg(target_arch = "x86_64")]
pub(crate) use avx::Avx8;

#[cfg(target_arch = "x86_64")]
mod avx {
    use std::arch::x86_64::*;
    use std::ops::{Add, BitAnd, Mul, Sub};

    use super::{Lanes8, HALF};

    /// One AVX register. Only for code compiled with AVX2 enabled and run
    /// where the CPU has it (`raster`'s run-time dispatch): every method
    /// executes AVX instructions.
    #[derive(Clone, Copy, Debug)]
    pub(crate) struct Avx8(__m256);

    // SAFETY (every `unsafe` below): the intrinsics need AVX, which the only
    // callers (the AVX2 passes, entered after run-time detection) have; the
    // unaligned loads and stores read and write the `HALF` values of an array.
    macro_rules! avx8_op {
        ($trait:ident, $method:ident, $intrinsic:ident) => {
            impl $trait for Avx8 {
                type Output = Self;
                #[inline(always)]
                fn $method(self, other: Self) -> Self {
                    Self(unsafe { $intrinsic(self.0, other.0) })
                }
            }
        };
    }
    avx8_op!(Add, add, _mm256_add_ps);
    avx8_op!(Sub, sub, _mm256_sub_ps);
    avx8_op!(Mul, mul, _mm256_mul_ps);
    avx8_op!(BitAnd, bitand, _mm256_and_ps);

    impl Lanes8 for Avx8 {
        #[inline(always)]
        fn splat(v: f32) -> Self {
            Self(unsafe { _mm256_set1_ps(v) })
        }

        #[inline(always)]
        fn halves(upper: f32, lower: f32) -> Self {
            Self(unsafe { _mm256_set_m128(_mm_set1_ps(lower), _mm_set1_ps(upper)) })
        }

        #[inline(always)]
        fn new(values: [f32; 8]) -> Self {
            Self(unsafe { _mm256_loadu_ps(values.as_ptr()) })
        }

        // Ordered, non-signalling comparisons: false where either is NaN, as
        // `wide`'s (and Rust's) are.
        #[inline(always)]
        fn simd_ge(self, other: Self) -> Self {
            Self(unsafe { _mm256_cmp_ps::<_CMP_GE_OQ>(self.0, other.0) })
        }

        #[inline(always)]
        fn simd_gt(self, other: Self) -> Self {
            Self(unsafe { _mm256_cmp_ps::<_CMP_GT_OQ>(self.0, other.0) })
        }

        #[inline(always)]
        fn simd_le(self, other: Self) -> Self {
            Self(unsafe { _mm256_cmp_ps::<_CMP_LE_OQ>(self.0, other.0) })
        }

        #[inline(always)]
        fn select(self, if_true: Self, if_false: Self) -> Self {
            // The mask's lanes are all ones or all zeros: blendv reads their sign bits.
            Self(unsafe { _mm256_blendv_ps(if_false.0, if_true.0, self.0) })
        }

        #[inline(always)]
        fn load(upper: &[f32; HALF], lower: &[f32; HALF]) -> Self {
            Self(unsafe { _mm256_set_m128(_mm_loadu_ps(lower.as_ptr()), _mm_loadu_ps(upper.as_ptr())) })
        }

        #[inline(always)]
        fn store(self, upper: &mut [f32; HALF], lower: &mut [f32; HALF]) {
            unsafe {
                _mm_storeu_ps(upper.as_mut_ptr(), _mm256_castps256_ps128(self.0));
                _mm_storeu_ps(lower.as_mut_ptr(), _mm256_extractf128_ps::<1>(self.0));
            }
        }

        #[inline(always)]
        fn load_bits(upper: &[u32; HALF], lower: &[u32; HALF]) -> Self {
            Self(unsafe { _mm256_set_m128(_mm_loadu_ps(lower.as_ptr().cast()), _mm_loadu_ps(upper.as_ptr().cast())) })
        }

        #[inline(always)]
        fn store_bits(self, upper: &mut [u32; HALF], lower: &mut [u32; HALF]) {
            unsafe {
                _mm_storeu_ps(upper.as_mut_ptr().cast(), _mm256_castps256_ps128(self.0));
                _mm_storeu_ps(lower.as_mut_ptr().cast(), _mm256_extractf128_ps::<1>(self.0));
            }
        }

        #[inline(always)]
        fn splat_bits(v: u32) -> Self {
            Self::splat(f32::from_bits(v))
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// `f()` from the baseline build of every dispatched pass, then from the
    /// build the CPU gets; one caller at a time, so each pair compares the
    /// two builds (other tests running meanwhile see the same bits either way).
    pub(crate) fn both_builds<T>(f: impl Fn() -> T) -> (T, T) {
        static LOCK: std::sync::Mutex<()> = std::sync::Mutex::new(());
        let _one_at_a_time = LOCK.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        BASELINE_ONLY.store(true, std::sync::atomic::Ordering::Relaxed);
        let baseline = f();
        BASELINE_ONLY.store(false, std::sync::atomic::Ordering::Relaxed);
        (baseline, f())
    }

    /// Values that expose rounding, signed zeros, subnormals, infinities and NaN.
    const VALUES: [f32; 8] = [1.0 / 3.0, -0.0, 0.0, 7.5e-39, f32::INFINITY, -2.5, f32::NAN, 1e30];

    fn shuffled(k: usize) -> [f32; 8] {
        std::array::from_fn(|i| VALUES[(i * 3 + k) % 8])
    }

    /// Every operation of `L`, lane by lane, against the scalar IEEE
    /// operation (masks as all-ones or all-zeros bits).
    fn follows_the_scalar_operations<L: Lanes8>() {
        let bits = |l: L| {
            let (mut upper, mut lower) = ([0u32; HALF], [0u32; HALF]);
            l.store_bits(&mut upper, &mut lower);
            [upper, lower].concat()
        };
        let mask = |f: fn(f32, f32) -> bool, a: &[f32; 8], b: &[f32; 8]| -> Vec<u32> { (0..8).map(|i| if f(a[i], b[i]) { u32::MAX } else { 0 }).collect() };
        for k in 0..8 {
            let (a, b) = (VALUES, shuffled(k));
            let (la, lb) = (L::new(a), L::new(b));
            let scalar = |f: fn(f32, f32) -> f32| (0..8).map(|i| f(a[i], b[i]).to_bits()).collect::<Vec<u32>>();
            assert_eq!(bits(la + lb), scalar(|x, y| x + y));
            assert_eq!(bits(la - lb), scalar(|x, y| x - y));
            assert_eq!(bits(la * lb), scalar(|x, y| x * y));
            assert_eq!(bits(la.simd_ge(lb)), mask(|x, y| x >= y, &a, &b));
            assert_eq!(bits(la.simd_gt(lb)), mask(|x, y| x > y, &a, &b));
            assert_eq!(bits(la.simd_le(lb)), mask(|x, y| x <= y, &a, &b));
            assert_eq!(bits(la.simd_ge(lb) & la.simd_le(lb)), mask(|x, y| x == y, &a, &b));
            let picked: Vec<u32> = (0..8).map(|i| if a[i] > b[i] { a[i] } else { b[i] }.to_bits()).collect();
            assert_eq!(bits(la.simd_gt(lb).select(la, lb)), picked);
        }
        let (upper, lower) = ([1.5f32, -0.0, 3.0, 4.0], [5.0f32, f32::NAN, 7.0, -8.0]);
        let (mut up, mut low) = ([0.0f32; HALF], [0.0f32; HALF]);
        L::load(&upper, &lower).store(&mut up, &mut low);
        assert_eq!([up, low].concat().iter().map(|v| v.to_bits()).collect::<Vec<_>>(), [upper, lower].concat().iter().map(|v| v.to_bits()).collect::<Vec<_>>());
        assert_eq!(bits(L::load_bits(&[1, 2, 3, u32::MAX], &[5, 0, 7, 8])), [1, 2, 3, u32::MAX, 5, 0, 7, 8]);
        assert_eq!(bits(L::splat_bits(0x7fc0_0001)), [0x7fc0_0001; 8], "a NaN's payload travels unchanged");
        assert_eq!(bits(L::halves(1.0, -2.0)), [[1.0f32.to_bits(); HALF], [(-2.0f32).to_bits(); HALF]].concat());
        assert_eq!(bits(L::splat(0.25)), [0.25f32.to_bits(); 8]);
    }

    #[test]
    fn pair4_follows_the_scalar_operations() {
        follows_the_scalar_operations::<Pair4>();
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn avx8_follows_the_scalar_operations() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            return;
        }
        #[target_feature(enable = "avx2")]
        fn run() {
            follows_the_scalar_operations::<Avx8>();
        }
        // SAFETY: the CPU has AVX2 (detected above).
        unsafe { run() };
    }
}
