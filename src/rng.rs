//! Seeded random streams: every random draw of idexp comes from a
//! `ChaCha8Rng::seed_from_u64(s)` whose seed s is derived from the design seed
//! and the indices of the unit of work (generation, repetition, block, start…)
//! by a SplitMix64 mixer, so that results do not depend on the thread count or
//! on the order in which units run.
//!
//! With the SplitMix64 constants γ = 0x9E3779B97F4A7C15 (the golden gamma) and
//! η = 0xD1B54A32D192ED03, and the SplitMix64 finaliser
//!
//! fin(z) = z₃ with z₁ = (z ⊕ z≫30)·0xBF58476D1CE4E5B9,
//! z₂ = (z₁ ⊕ z₁≫27)·0x94D049BB133111EB, z₃ = z₂ ⊕ z₂≫31 (wrapping u64),
//!
//! there are two derivations, kept apart because changing either would change
//! every seeded output of the designs that use it:
//!
//! - [`mix`]`(s, a, b)` = fin(s ⊕ a·γ ⊕ b·η) — the genetic search
//!   (generation streams) and the rigid-body simulator (`mix(s, unit, 0)`,
//!   per period or repetition);
//! - [`sub_seed`]`(s, stream, i)` = fin((s ⊕ stream·γ ⊕ i·η) + γ) — one full
//!   SplitMix64 step; the FRF pipeline (multisine phases, truth perturbation,
//!   noise, multistart points), with stream identifiers in
//!   `frf::multisine::streams`.

const GAMMA: u64 = 0x9E37_79B9_7F4A_7C15;
const ETA: u64 = 0xD1B5_4A32_D192_ED03;

/// The SplitMix64 finaliser (a bijection of u64 with good avalanche).
pub fn finalize(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Seed of unit (a, b) derived from `seed`: fin(seed ⊕ a·γ ⊕ b·η).
pub fn mix(seed: u64, a: u64, b: u64) -> u64 {
    finalize(seed ^ a.wrapping_mul(GAMMA) ^ b.wrapping_mul(ETA))
}

/// Seed of unit `index` of stream `stream` derived from `seed`:
/// fin((seed ⊕ stream·γ ⊕ index·η) + γ).
pub fn sub_seed(seed: u64, stream: u64, index: u64) -> u64 {
    finalize((seed ^ stream.wrapping_mul(GAMMA) ^ index.wrapping_mul(ETA)).wrapping_add(GAMMA))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The arithmetic of the three mixers this module replaced, written out.
    fn old_ga(seed: u64, a: u64, b: u64) -> u64 {
        let mut z = seed ^ a.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ b.wrapping_mul(0xD1B5_4A32_D192_ED03);
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn old_frf(seed: u64, stream: u64, index: u64) -> u64 {
        let mut z = seed ^ stream.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ index.wrapping_mul(0xD1B5_4A32_D192_ED03);
        z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn old_sim(seed: u64, index: u64) -> u64 {
        let mut z = seed ^ index.wrapping_mul(0x9E37_79B9_7F4A_7C15);
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    #[test]
    fn the_mixers_keep_the_old_seeds() {
        for seed in [0u64, 1, 42, 2024, u64::MAX, 0x1234_5678_9abc_def0] {
            for a in [0u64, 1, 2, 3, 99, 100_000, u64::MAX] {
                for b in [0u64, 1, 7, u64::MAX] {
                    assert_eq!(mix(seed, a, b), old_ga(seed, a, b));
                    assert_eq!(sub_seed(seed, a, b), old_frf(seed, a, b));
                }
                assert_eq!(mix(seed, a, 0), old_sim(seed, a));
            }
        }
    }

    #[test]
    fn the_two_derivations_differ() {
        assert_ne!(mix(1, 2, 3), sub_seed(1, 2, 3));
        assert_ne!(mix(1, 2, 3), mix(1, 3, 2));
    }
}
