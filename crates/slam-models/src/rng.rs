//! Seeded random streams: the one place where slam-rs derives independent random streams
//! from a user seed.
//!
//! Every random draw of a filter or the simulator comes from a [`Pcg64Mcg`] whose state is
//! a pure function of the user seed and of *where* the draw is made (a particle at a filter
//! step, a part of a simulation), never of the order in which threads run. The mixing is
//! splitmix64's finaliser ([`splitmix64`]), a bijection of 64-bit words with full
//! avalanche, so that neighbouring inputs (particle 3 and 4, step 10 and 11) give unrelated
//! streams.
//!
//! The three derivations below differ only in how they nest the mixer; each is fixed
//! forever, because changing one changes every output of the crates that use it
//! (grid FastSLAM, landmark FastSLAM, the simulator).

use rand::SeedableRng;
pub use rand_pcg::Pcg64Mcg;

/// splitmix64's finaliser (Steele, Lea & Flood, OOPSLA 2014; Vigna's `splitmix64.c`): a
/// bijective 64-bit mixer, z ↦ mix(z + 0x9E3779B97F4A7C15) with two xor-shift-multiply
/// rounds and a final xor-shift.
#[inline]
pub fn splitmix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The random stream of particle `index` at filter step `step` for `seed`:
/// PCG seeded (through `seed_from_u64`) with m(m(m(seed) ⊕ step) ⊕ index), m =
/// [`splitmix64`], ⊕ = xor. Grid FastSLAM's per-particle streams (its resampler draws from
/// `index = u64::MAX`).
pub fn particle_stream(seed: u64, step: u64, index: u64) -> Pcg64Mcg {
    Pcg64Mcg::seed_from_u64(splitmix64(splitmix64(splitmix64(seed) ^ step) ^ index))
}

/// The random stream of particle `index` at filter tick `tick` for `seed`, with all 128
/// bits of PCG's state set: hi = m(seed ⊕ m(tick ⊕ m(index))), lo = m(hi ⊕
/// 0xD1B54A32D192ED03), state = hi·2⁶⁴ + lo (m = [`splitmix64`]). Landmark FastSLAM's
/// per-particle streams.
pub fn particle_stream_wide(seed: u64, tick: u64, index: u64) -> Pcg64Mcg {
    let hi = splitmix64(seed ^ splitmix64(tick ^ splitmix64(index)));
    let lo = splitmix64(hi ^ 0xD1B5_4A32_D192_ED03);
    Pcg64Mcg::new(((hi as u128) << 64) | lo as u128)
}

/// The stream of the independent part `tag` (world, motion noise, sensor noise, …) of a
/// simulation with `seed`: PCG seeded with m(seed ⊕ m(tag · 0xA24BAED4963EE407)),
/// m = [`splitmix64`]. The simulator's streams.
pub fn tagged_stream(seed: u64, tag: u64) -> Pcg64Mcg {
    Pcg64Mcg::seed_from_u64(splitmix64(
        seed ^ splitmix64(tag.wrapping_mul(0xA24B_AED4_963E_E407)),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::Rng;

    /// The published splitmix64 sequence for seed 1234567 (Vigna's `splitmix64.c`: the
    /// generator adds the increment to its state and returns the finaliser of the new
    /// state; `splitmix64` adds it itself, so state s gives splitmix64(s)).
    #[test]
    fn splitmix64_matches_the_reference_sequence() {
        let expected: [u64; 5] = [
            6457827717110365317,
            3203168211198807973,
            9817491932198370423,
            4593380528125082431,
            16408922859458223821,
        ];
        let mut state = 1_234_567u64;
        for e in expected {
            assert_eq!(splitmix64(state), e);
            state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        }
    }

    /// Streams are pure functions of their inputs and differ when any input differs.
    #[test]
    fn streams_are_reproducible_and_distinct() {
        let first = |mut r: Pcg64Mcg| r.random::<u64>();
        assert_eq!(
            first(particle_stream(7, 3, 11)),
            first(particle_stream(7, 3, 11))
        );
        let mut seen = std::collections::BTreeSet::new();
        for (s, t, i) in [(7, 3, 11), (8, 3, 11), (7, 4, 11), (7, 3, 12)] {
            assert!(seen.insert(first(particle_stream(s, t, i))));
            assert!(seen.insert(first(particle_stream_wide(s, t, i))));
        }
        assert_ne!(first(tagged_stream(1, 2)), first(tagged_stream(1, 3)));
        assert_ne!(first(tagged_stream(1, 2)), first(tagged_stream(2, 2)));
    }
}
