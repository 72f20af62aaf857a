//! Four- and eight-lane f32 vectors behind one interface, so that a hot loop is written once and
//! compiled twice: four-wide on glam's [`Vec4`] (SSE2 on every x86-64, NEON on aarch64), and
//! eight-wide on [`F32x8`] inside a function compiled for AVX2 and chosen at run time (see
//! [`width`]). DACRT's per-call projection of every triangle (the screen-space culling that
//! replaces the cone bound of Mora 2011 §3.3 for camera rays) is the loop that pays for it:
//! dragon frame 116 → 110 ms.
//!
//! [`Wide`] is plain Rust over `[f32; N]` that LLVM vectorizes (not the `wide` crate, whose width
//! is fixed when it is compiled, not when it runs); its operations reproduce SSE's results (`min`
//! and `max` return the second operand when either is NaN, as `minps` does; `ceil` and `floor`
//! give the same numbers, up to the sign of a zero), so both widths give identical rectangles:
//! tests check each operation lane by lane and the projection at both widths.

use glam::{BVec4A, Vec4};
use std::ops::{Add, BitAnd, BitOr, Div, Mul, Not, Sub};

/// A vector of `N` f32 lanes with SSE semantics (see the module doc).
pub trait Lanes:
    Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + Div<Output = Self>
{
    /// Lane mask.
    type Mask: Copy
        + BitAnd<Output = Self::Mask>
        + BitOr<Output = Self::Mask>
        + Not<Output = Self::Mask>;
    /// Number of lanes.
    const N: usize;
    /// Every lane `v`.
    fn splat(v: f32) -> Self;
    /// Every lane `v.x`, from a `v` whose four lanes are equal (kept splatted in memory: four
    /// lanes load it as it is, a plain load instead of a load and a shuffle without AVX).
    fn from_splat4(v: Vec4) -> Self;
    /// Lane `i` is `f(i)`.
    fn from_fn(f: impl FnMut(usize) -> f32) -> Self;
    /// Lane `i`.
    fn lane(self, i: usize) -> f32;
    /// `|x|` (the sign bit cleared).
    fn abs(self) -> Self;
    /// `±1` by the sign bit; NaN stays NaN.
    fn signum(self) -> Self;
    /// Lanes whose sign bit is set (`-0.0` and negative NaNs included).
    fn sign_bit(self) -> Self::Mask;
    /// `self < o ? self : o` (`minps`).
    fn min(self, o: Self) -> Self;
    /// `self > o ? self : o` (`maxps`).
    fn max(self, o: Self) -> Self;
    /// Rounded up to an integer.
    fn ceil(self) -> Self;
    /// Rounded down to an integer.
    fn floor(self) -> Self;
    /// `self > o` (false for NaN).
    fn cmpgt(self, o: Self) -> Self::Mask;
    /// `self >= o`.
    fn cmpge(self, o: Self) -> Self::Mask;
    /// `self <= o`.
    fn cmple(self, o: Self) -> Self::Mask;
    /// `self == o`.
    fn cmpeq(self, o: Self) -> Self::Mask;
    /// `self != o` (true for NaN).
    fn cmpne(self, o: Self) -> Self::Mask;
    /// Every lane of the mask `v`.
    fn mask_splat(v: bool) -> Self::Mask;
    /// Bit `i` set when lane `i` of `m` is.
    fn bitmask(m: Self::Mask) -> u32;
    /// Lane `i` from `a` where `m` holds, from `b` elsewhere.
    fn select(m: Self::Mask, a: Self, b: Self) -> Self;
}

impl Lanes for Vec4 {
    type Mask = BVec4A;
    const N: usize = 4;
    #[inline(always)]
    fn splat(v: f32) -> Self {
        Vec4::splat(v)
    }
    #[inline(always)]
    fn from_splat4(v: Vec4) -> Self {
        v
    }
    #[inline(always)]
    fn from_fn(mut f: impl FnMut(usize) -> f32) -> Self {
        Vec4::new(f(0), f(1), f(2), f(3))
    }
    #[inline(always)]
    fn lane(self, i: usize) -> f32 {
        self[i]
    }
    #[inline(always)]
    fn abs(self) -> Self {
        Vec4::abs(self)
    }
    #[inline(always)]
    fn signum(self) -> Self {
        Vec4::signum(self)
    }
    #[inline(always)]
    fn sign_bit(self) -> BVec4A {
        Vec4::ONE.copysign(self).cmplt(Vec4::ZERO)
    }
    #[inline(always)]
    fn min(self, o: Self) -> Self {
        Vec4::min(self, o)
    }
    #[inline(always)]
    fn max(self, o: Self) -> Self {
        Vec4::max(self, o)
    }
    #[inline(always)]
    fn ceil(self) -> Self {
        Vec4::ceil(self)
    }
    #[inline(always)]
    fn floor(self) -> Self {
        Vec4::floor(self)
    }
    #[inline(always)]
    fn cmpgt(self, o: Self) -> BVec4A {
        Vec4::cmpgt(self, o)
    }
    #[inline(always)]
    fn cmpge(self, o: Self) -> BVec4A {
        Vec4::cmpge(self, o)
    }
    #[inline(always)]
    fn cmple(self, o: Self) -> BVec4A {
        Vec4::cmple(self, o)
    }
    #[inline(always)]
    fn cmpeq(self, o: Self) -> BVec4A {
        Vec4::cmpeq(self, o)
    }
    #[inline(always)]
    fn cmpne(self, o: Self) -> BVec4A {
        Vec4::cmpne(self, o)
    }
    #[inline(always)]
    fn mask_splat(v: bool) -> BVec4A {
        BVec4A::splat(v)
    }
    #[inline(always)]
    fn bitmask(m: BVec4A) -> u32 {
        m.bitmask()
    }
    #[inline(always)]
    fn select(m: BVec4A, a: Self, b: Self) -> Self {
        Vec4::select(m, a, b)
    }
}

/// `N` f32 lanes as plain Rust (see the module doc).
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
pub struct Wide<const N: usize>(pub [f32; N]);

/// [`Wide`]'s mask: all ones or all zeros per lane.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(C, align(64))]
pub struct WideMask<const N: usize>(pub [u32; N]);

/// Eight lanes: AVX2's width.
pub type F32x8 = Wide<8>;
/// [`F32x8`]'s mask.
pub type M32x8 = WideMask<8>;

#[inline(always)]
fn map<const N: usize>(a: Wide<N>, f: impl Fn(f32) -> f32) -> Wide<N> {
    Wide(std::array::from_fn(|i| f(a.0[i])))
}

#[inline(always)]
fn zip<const N: usize>(a: Wide<N>, b: Wide<N>, f: impl Fn(f32, f32) -> f32) -> Wide<N> {
    Wide(std::array::from_fn(|i| f(a.0[i], b.0[i])))
}

#[inline(always)]
fn test<const N: usize>(a: Wide<N>, b: Wide<N>, f: impl Fn(f32, f32) -> bool) -> WideMask<N> {
    WideMask(std::array::from_fn(
        |i| if f(a.0[i], b.0[i]) { !0 } else { 0 },
    ))
}

macro_rules! wide_op {
    ($tr:ident, $f:ident, $op:tt) => {
        impl<const N: usize> $tr for Wide<N> {
            type Output = Wide<N>;
            #[inline(always)]
            fn $f(self, o: Wide<N>) -> Wide<N> {
                zip(self, o, |a, b| a $op b)
            }
        }
    };
}
wide_op!(Add, add, +);
wide_op!(Sub, sub, -);
wide_op!(Mul, mul, *);
wide_op!(Div, div, /);

macro_rules! mask_op {
    ($tr:ident, $f:ident, $op:tt) => {
        impl<const N: usize> $tr for WideMask<N> {
            type Output = WideMask<N>;
            #[inline(always)]
            fn $f(self, o: WideMask<N>) -> WideMask<N> {
                WideMask(std::array::from_fn(|i| self.0[i] $op o.0[i]))
            }
        }
    };
}
mask_op!(BitAnd, bitand, &);
mask_op!(BitOr, bitor, |);

impl<const N: usize> Not for WideMask<N> {
    type Output = WideMask<N>;
    #[inline(always)]
    fn not(self) -> WideMask<N> {
        WideMask(self.0.map(|m| !m))
    }
}

impl<const N: usize> Lanes for Wide<N> {
    type Mask = WideMask<N>;
    const N: usize = N;
    #[inline(always)]
    fn splat(v: f32) -> Self {
        Wide([v; N])
    }
    #[inline(always)]
    fn from_splat4(v: Vec4) -> Self {
        Wide([v.x; N])
    }
    #[inline(always)]
    fn from_fn(f: impl FnMut(usize) -> f32) -> Self {
        Wide(std::array::from_fn(f))
    }
    #[inline(always)]
    fn lane(self, i: usize) -> f32 {
        self.0[i]
    }
    #[inline(always)]
    fn abs(self) -> Self {
        map(self, |a| f32::from_bits(a.to_bits() & 0x7fff_ffff))
    }
    #[inline(always)]
    fn signum(self) -> Self {
        // As glam's SSE `signum`: the sign bit on 1.0, NaN kept.
        map(self, |a| {
            let s = f32::from_bits(a.to_bits() & 0x8000_0000 | 1.0f32.to_bits());
            if a.is_nan() {
                a
            } else {
                s
            }
        })
    }
    #[inline(always)]
    fn sign_bit(self) -> WideMask<N> {
        WideMask(self.0.map(|a| ((a.to_bits() as i32) >> 31) as u32))
    }
    #[inline(always)]
    fn min(self, o: Self) -> Self {
        zip(self, o, |a, b| if a < b { a } else { b })
    }
    #[inline(always)]
    fn max(self, o: Self) -> Self {
        zip(self, o, |a, b| if a > b { a } else { b })
    }
    #[inline(always)]
    fn ceil(self) -> Self {
        map(self, f32::ceil)
    }
    #[inline(always)]
    fn floor(self) -> Self {
        map(self, f32::floor)
    }
    #[inline(always)]
    fn cmpgt(self, o: Self) -> WideMask<N> {
        test(self, o, |a, b| a > b)
    }
    #[inline(always)]
    fn cmpge(self, o: Self) -> WideMask<N> {
        test(self, o, |a, b| a >= b)
    }
    #[inline(always)]
    fn cmple(self, o: Self) -> WideMask<N> {
        test(self, o, |a, b| a <= b)
    }
    #[inline(always)]
    fn cmpeq(self, o: Self) -> WideMask<N> {
        test(self, o, |a, b| a == b)
    }
    #[inline(always)]
    fn cmpne(self, o: Self) -> WideMask<N> {
        test(self, o, |a, b| a != b)
    }
    #[inline(always)]
    fn mask_splat(v: bool) -> WideMask<N> {
        WideMask([if v { !0 } else { 0 }; N])
    }
    #[inline(always)]
    fn bitmask(m: WideMask<N>) -> u32 {
        (0..N).fold(0, |b, i| b | (m.0[i] >> 31) << i)
    }
    #[inline(always)]
    fn select(m: WideMask<N>, a: Self, b: Self) -> Self {
        Wide(std::array::from_fn(|i| {
            f32::from_bits(a.0[i].to_bits() & m.0[i] | b.0[i].to_bits() & !m.0[i])
        }))
    }
}

/// The lane width the hot loops run at on this CPU.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Width {
    /// [`Vec4`]: SSE2 on x86-64, NEON on aarch64.
    Four,
    /// [`F32x8`] in code compiled for AVX2.
    Eight,
}

/// Eight lanes when the CPU has AVX2, else four; checked once. `RAYSIFT_LANES=4` in the
/// environment forces four (to measure the portable path on an AVX2 machine). Sixteen lanes
/// (AVX-512) measured slower than eight on the dragon's projection (117 vs 110 ms per frame),
/// so there is no such path.
pub fn width() -> Width {
    #[cfg(target_arch = "x86_64")]
    {
        static W: std::sync::OnceLock<Width> = std::sync::OnceLock::new();
        *W.get_or_init(|| {
            let forced4 = std::env::var("RAYSIFT_LANES").is_ok_and(|v| v == "4");
            // Every AVX2 CPU has POPCNT too; checked as well, for the lane-mask counts.
            if !forced4
                && std::arch::is_x86_feature_detected!("avx2")
                && std::arch::is_x86_feature_detected!("popcnt")
            {
                Width::Eight
            } else {
                Width::Four
            }
        })
    }
    #[cfg(not(target_arch = "x86_64"))]
    Width::Four
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// Values that stress the SSE semantics: signed zeros, halves, huge, infinite, NaN.
    fn special(rng: &mut impl Rng) -> f32 {
        const S: [f32; 12] = [
            0.0,
            -0.0,
            0.5,
            -0.5,
            -1.5,
            8388607.5,
            -8388609.0,
            1e30,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            f32::MIN_POSITIVE,
        ];
        if rng.gen_bool(0.3) {
            S[rng.gen_range(0..S.len())]
        } else {
            rng.gen_range(-1e4f32..1e4)
        }
    }

    #[test]
    fn eight_lanes_equal_four() {
        // Each operation on `F32x8` equals `Vec4`'s on both halves, bit for bit (NaN payloads
        // included), so code generic over `Lanes` answers the same at either width.
        let mut rng = rand_pcg::Pcg64::seed_from_u64(8);
        let bits4 = |v: Vec4| v.to_array().map(f32::to_bits);
        for _ in 0..20_000 {
            let a: [f32; 8] = std::array::from_fn(|_| special(&mut rng));
            let b: [f32; 8] = std::array::from_fn(|_| special(&mut rng));
            let (a8, b8) = (Wide(a), Wide(b));
            let half = |v: &[f32; 8], h: usize| Vec4::from_slice(&v[4 * h..4 * h + 4]);
            type Op8 = fn(F32x8, F32x8) -> F32x8;
            type Op4 = fn(Vec4, Vec4) -> Vec4;
            let ops: [(Op8, Op4); 10] = [
                (|a, b| a + b, |a, b| a + b),
                (|a, b| a - b, |a, b| a - b),
                (|a, b| a * b, |a, b| a * b),
                (|a, b| a / b, |a, b| a / b),
                (|a, b| a.min(b), |a, b| a.min(b)),
                (|a, b| a.max(b), |a, b| a.max(b)),
                (|a, _| Lanes::abs(a), |a, _| a.abs()),
                (|a, _| Lanes::signum(a), |a, _| a.signum()),
                (|a, _| Lanes::ceil(a), |a, _| a.ceil()),
                (|a, _| Lanes::floor(a), |a, _| a.floor()),
            ];
            for (k, (f8, f4)) in ops.iter().enumerate() {
                let r8 = f8(a8, b8).0.map(f32::to_bits);
                for h in 0..2 {
                    let r4 = bits4(f4(half(&a, h), half(&b, h)));
                    // ceil/floor may differ in the sign of a zero result (-0.5 → -0 or +0):
                    // the same number, and the callers only compare and convert them.
                    let same = r8[4 * h..4 * h + 4].iter().zip(r4).all(|(&x, y)| {
                        x == y || (k >= 8 && f32::from_bits(x) == f32::from_bits(y))
                    });
                    assert!(same, "op {k} on {a:?} {b:?}");
                }
            }
            type Cmp8 = fn(F32x8, F32x8) -> M32x8;
            type Cmp4 = fn(Vec4, Vec4) -> BVec4A;
            let cmps: [(Cmp8, Cmp4); 5] = [
                (|a, b| a.cmpgt(b), |a, b| a.cmpgt(b)),
                (|a, b| a.cmpge(b), |a, b| a.cmpge(b)),
                (|a, b| a.cmple(b), |a, b| a.cmple(b)),
                (|a, b| a.cmpeq(b), |a, b| a.cmpeq(b)),
                (|a, b| a.cmpne(b), |a, b| a.cmpne(b)),
            ];
            let sign8 = F32x8::bitmask(a8.sign_bit());
            let sign4 = Lanes::sign_bit(half(&a, 0)).bitmask()
                | Lanes::sign_bit(half(&a, 1)).bitmask() << 4;
            assert_eq!(sign8, sign4);
            assert_eq!(
                sign8,
                (0..8).fold(0, |m, i| m | (a[i].is_sign_negative() as u32) << i)
            );
            for (f8, f4) in cmps {
                let m8 = f8(a8, b8);
                let m4 = f4(half(&a, 0), half(&b, 0)).bitmask()
                    | f4(half(&a, 1), half(&b, 1)).bitmask() << 4;
                assert_eq!(F32x8::bitmask(m8), m4);
                let s8 = F32x8::select(m8, a8, b8);
                let s = F32x8::bitmask(!m8 & m8 | F32x8::mask_splat(false));
                assert_eq!(s, 0);
                for i in 0..8 {
                    let want = if m4 >> i & 1 != 0 { a[i] } else { b[i] };
                    assert_eq!(s8.0[i].to_bits(), want.to_bits());
                }
            }
        }
    }
}
