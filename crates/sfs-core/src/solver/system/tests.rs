//! The system's tests: the right-hand side against the energy's gradient, symmetry,
//! the data part across blocks of rows, stashed depths, the norms, and the weights'
//! and the kept entries' bookkeeping.

use super::layout::{KZ_PLANES, MASK_PLANES, SLOT_OFFSET};
use super::rows::{
    BACKWARD, DATA_ONLY_FORWARD, KEPT_ENTRY, KzRows, SHARED_FORWARD, SMOOTH_ONLY_FORWARD, kz_row,
};
use super::*;

use crate::camera::Intrinsics;
use crate::cancel::Uncancelled;
use crate::grid::Confidence;
use crate::model::{Lambertian, LevelGeometry};
use crate::solver::prepare::level_energy;

/// A small level with a random-looking smooth depth and a domain hole.
fn small_level(domain_hole: bool) -> (PyramidLevel<'static>, Grid<f64>) {
    let (w, h) = (9, 8);
    let camera = Intrinsics::centred(12.0, w, h);
    let geometry = LevelGeometry::new(w, h, w, h, camera);
    let depth = Grid::from_fn(w, h, |c, r| {
        2.0 + 0.05 * ((c * 7 + r * 3) as f64).sin() + 0.03 * (r as f64 * 0.9).cos()
    });
    let image = Grid::from_fn(w, h, |c, r| 0.3 + 0.01 * ((c * 5 + r * 11) as f64).cos());
    let confidence = Grid::from_fn(w, h, |c, r| if (c + r) % 5 == 0 { 0.5 } else { 1.0 });
    let domain = Grid::from_fn(w, h, |c, r| {
        !(domain_hole && (c == 0 && r < 3 || (c == 5 && r == 4)))
    });
    (
        PyramidLevel {
            geometry,
            image: std::borrow::Cow::Owned(image),
            confidence: Confidence::from_grid(confidence, Cancel::NEVER).uncancelled(),
            domain,
        },
        depth,
    )
}

#[test]
fn rhs_is_minus_half_the_energy_gradient_and_matrix_is_symmetric() {
    for hole in [false, true] {
        let (level, depth) = small_level(hole);
        let model = Lambertian {
            intensity_scale: 1.3,
        };
        let (alpha, lambda) = (0.7, 0.05);
        let mut system = LinearSystem::new(&level, Cancel::NEVER).uncancelled();
        assert!(
            system
                .linearise_data(&model, &level, &depth, Derivatives::Exact, Cancel::NEVER)
                .uncancelled()
        );
        system
            .add_smoothness(&level, &depth, alpha, lambda, Cancel::NEVER)
            .uncancelled();
        let energy = |z: &Grid<f64>| {
            level_energy(&model, &level, z, alpha, lambda, Cancel::NEVER)
                .uncancelled()
                .total
        };
        let (w, h) = depth.size();
        for q in 0..w * h {
            if !level.domain.as_slice()[q] {
                continue;
            }
            let e = 1e-6;
            let mut plus = depth.clone();
            plus.as_mut_slice()[q] += e;
            let mut minus = depth.clone();
            minus.as_mut_slice()[q] -= e;
            let gradient = (energy(&plus) - energy(&minus)) / (2.0 * e);
            assert!(
                (gradient + 2.0 * f64::from(system.row(q % w, q / w).rhs)).abs()
                    < 1e-5 * (1.0 + gradient.abs()),
                "hole={hole} q={q}: numeric {gradient} vs -2 rhs {}",
                -2.0 * f64::from(system.row(q % w, q / w).rhs)
            );
        }
        let rows = system.explicit_rows();
        for (i, row) in rows.iter().enumerate() {
            for &(j, a) in row {
                let back = rows[j].iter().find(|(k, _)| *k == i).map(|(_, v)| *v);
                let back = back.expect("symmetric sparsity");
                assert!(
                    (a - back).abs() <= 1e-5 * a.abs().max(1e-3),
                    "{i},{j}: {a} vs {back}"
                );
            }
        }
    }
}

#[test]
fn the_data_part_is_whole_across_the_blocks_of_rows() {
    // Wide enough that the data part streams its Jacobian in several
    // blocks of rows: the rows beside a block's edge read the Jacobian
    // of the next block's first row, computed twice. The right-hand
    // side there is still minus half the data energy's gradient.
    let (w, h) = (300, 3 * MIN_DATA_BLOCK_ROWS);
    assert!(rows_per_task(w).max(MIN_DATA_BLOCK_ROWS) < h);
    let camera = Intrinsics::centred(300.0, w, h);
    let depth = Grid::from_fn(w, h, |c, r| {
        2.0 + 0.05 * ((c * 7 + r * 3) as f64 * 0.1).sin() + 0.03 * (r as f64 * 0.2).cos()
    });
    let level = PyramidLevel {
        geometry: LevelGeometry::new(w, h, w, h, camera),
        image: std::borrow::Cow::Owned(Grid::from_fn(w, h, |c, r| {
            0.25 + 0.01 * ((c * 5 + r * 11) as f64).cos()
        })),
        confidence: Confidence::from_grid(
            Grid::from_fn(w, h, |c, r| if (c + r) % 5 == 0 { 0.5 } else { 1.0 }),
            Cancel::NEVER,
        )
        .uncancelled(),
        domain: Grid::filled(w, h, true),
    };
    let model = Lambertian {
        intensity_scale: 1.3,
    };
    let mut system = linearised(&level, &depth, &model);
    // alpha 0: the rows are the data part alone.
    system
        .add_smoothness(&level, &depth, 0.0, 1.0, Cancel::NEVER)
        .uncancelled();
    let data_energy = |z: &Grid<f64>| {
        level_energy(&model, &level, z, 0.0, 1.0, Cancel::NEVER)
            .uncancelled()
            .data
    };
    let edge = rows_per_task(w).max(MIN_DATA_BLOCK_ROWS);
    for r in [edge - 2, edge - 1, edge, edge + 1, 2 * edge - 1, 2 * edge] {
        for c in [1, 150, 298] {
            let e = 1e-6;
            let mut plus = depth.clone();
            *plus.at_mut(c, r) += e;
            let mut minus = depth.clone();
            *minus.at_mut(c, r) -= e;
            let gradient = (data_energy(&plus) - data_energy(&minus)) / (2.0 * e);
            let rhs = f64::from(system.row(c, r).rhs);
            assert!(
                (gradient + 2.0 * rhs).abs() < 1e-5 * (1.0 + gradient.abs()),
                "({c}, {r}): numeric {gradient} vs -2 rhs {}",
                -2.0 * rhs
            );
        }
    }
}

/// A new system on `level`, its data part linearised at `depth`.
fn linearised(level: &PyramidLevel, depth: &Grid<f64>, model: &Lambertian) -> LinearSystem {
    let mut system = LinearSystem::new(level, Cancel::NEVER).uncancelled();
    assert!(
        system
            .linearise_data(model, level, depth, Derivatives::Exact, Cancel::NEVER)
            .uncancelled()
    );
    system
}

#[test]
fn a_stashed_depth_comes_back_bit_for_bit_and_needs_a_new_linearisation() {
    let (level, depth) = small_level(true);
    let model = Lambertian {
        intensity_scale: 1.0,
    };
    let mut system = linearised(&level, &depth, &model);
    let odd = Grid::from_fn(9, 8, |c, r| {
        [f64::MIN_POSITIVE, -0.0, 1e300, 2.0 + (c * r) as f64 * 1e-17][(c + r) % 4]
    });
    system.stash_depth(&odd);
    let mut back = Grid::filled(9, 8, 0.0);
    system.restore_depth(&mut back);
    for (a, b) in odd.as_slice().iter().zip(back.as_slice()) {
        assert_eq!(a.to_bits(), b.to_bits());
    }
    let assembled = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        system
            .add_smoothness(&level, &depth, 1.0, 1.0, Cancel::NEVER)
            .uncancelled()
    }));
    assert!(assembled.is_err(), "the data part was overwritten");
    assert!(
        system
            .linearise_data(&model, &level, &depth, Derivatives::Exact, Cancel::NEVER)
            .uncancelled()
    );
    system
        .add_smoothness(&level, &depth, 1.0, 1.0, Cancel::NEVER)
        .uncancelled();
}

#[test]
fn the_rhs_norm_is_the_residual_norm_at_zero_step() {
    // A domain with holes: unsolved pixels count in neither.
    let mut system = test_system(37, 29, |c, r| (c * 3 + r) % 11 != 0, 0.4, 1e-2);
    system.clear_dz(Cancel::NEVER).uncancelled();
    let rhs = system.rhs_norm_squared(Cancel::NEVER).uncancelled();
    let residual = system.residual_norm_squared(Cancel::NEVER).uncancelled();
    assert!(rhs > 0.0);
    assert!(
        (rhs - residual).abs() <= 1e-12 * residual,
        "{rhs} vs {residual}"
    );
    // Not at a non-zero step.
    system.dz_padded.iter_mut().for_each(|x| *x = 0.01);
    let moved = system.residual_norm_squared(Cancel::NEVER).uncancelled();
    assert!((moved - rhs).abs() > 1e-6 * rhs, "{moved} vs {rhs}");
}

#[test]
fn weights_alone_leave_the_rows_until_they_are_assembled() {
    let (level, depth) = small_level(true);
    let model = Lambertian {
        intensity_scale: 1.0,
    };
    let assembled = || {
        let mut system = linearised(&level, &depth, &model);
        system
            .add_smoothness(&level, &depth, 0.5, 0.1, Cancel::NEVER)
            .uncancelled();
        system
    };
    let (mut fused, mut split) = (assembled(), assembled());
    // A step moves Psi': the weights change, the rows stay until assembled.
    for system in [&mut fused, &mut split] {
        system
            .dz_padded
            .iter_mut()
            .enumerate()
            .for_each(|(i, x)| *x = 0.05 * (i as f32 * 0.37).sin());
    }
    let before = split.coefficients.clone();
    let change = split
        .update_weights(&level, &depth, 0.1, Cancel::NEVER)
        .uncancelled();
    assert!(change > 0.0);
    assert_eq!(split.coefficients, before);
    split
        .assemble(&level, &depth, 0.5, Cancel::NEVER)
        .uncancelled();
    assert_eq!(
        fused
            .add_smoothness(&level, &depth, 0.5, 0.1, Cancel::NEVER)
            .uncancelled(),
        change
    );
    assert_eq!(split.coefficients, fused.coefficients);
    assert_ne!(split.coefficients, before);
}

#[test]
fn the_kept_entries_are_the_diagonal_and_the_forward_half() {
    for (s, &(sx, sy)) in SLOT_OFFSET.iter().enumerate() {
        for (t, &(tx, ty)) in SLOT_OFFSET.iter().enumerate() {
            let offset = (tx - sx, ty - sy);
            let entry = KEPT_ENTRY[s][t];
            assert!(STENCIL.contains(&offset));
            if offset == (0, 0) {
                assert_eq!(entry, 0);
            } else if let Some(k) = FORWARD.iter().position(|&f| f == offset) {
                assert_eq!(usize::from(entry), 1 + k);
            } else {
                assert_eq!(entry, BACKWARD);
                assert!(FORWARD.contains(&(-offset.0, -offset.1)));
            }
        }
    }
}

#[test]
fn kz_rows_are_the_clamped_stencils_bit_for_bit() {
    // Domain holes at the edges and inside, and widths below and above
    // the interior loop's three columns: every value equals the stencils
    // evaluated pixel by pixel with neighbours clamped to the grid (the
    // values the system once stored for the level).
    for (w, h) in [(9, 8), (2, 5), (1, 3), (37, 6)] {
        let depth = Grid::from_fn(w, h, |c, r| {
            1e3 + 0.05 * ((c * 7 + r * 3) as f64).sin() + 0.03 * (r as f64 * 0.9).cos()
        });
        let level = PyramidLevel {
            geometry: LevelGeometry::new(w, h, w, h, Intrinsics::centred(12.0, w, h)),
            image: std::borrow::Cow::Owned(Grid::filled(w, h, 0.3)),
            confidence: Confidence::from_grid(Grid::filled(w, h, 1.0), Cancel::NEVER).uncancelled(),
            domain: Grid::from_fn(w, h, |c, r| (c * 5 + r * 3) % 7 != 0 || c + 1 == w),
        };
        let system = LinearSystem::new(&level, Cancel::NEVER).uncancelled();
        let pw = system.padded_width();
        let z = |c: usize, dc: isize, r: usize, dr: isize| {
            let cc = c.saturating_add_signed(dc).min(w - 1);
            let rr = r.saturating_add_signed(dr).min(h - 1);
            *depth.at(cc, rr)
        };
        let mut rows = KzRows::new(pw);
        for r in 0..h {
            let mask_block = &system.masks[(r + HALO) * MASK_PLANES * pw..][..MASK_PLANES * pw];
            let mut out = vec![f32::NAN; KZ_PLANES * pw];
            kz_row(depth.as_slice(), w, h, r, mask_block, &mut out);
            let around = rows.around(depth.as_slice(), (w, h), &system.masks, r);
            // The same values (the halo, which `kz_row` leaves, aside).
            for k in 0..KZ_PLANES {
                let inside = k * pw + HALO..k * pw + HALO + w;
                assert_eq!(around[1][inside.clone()], out[inside]);
            }
            for c in 0..w {
                let centre = 2.0 * depth.at(c, r);
                let want = [
                    z(c, -1, r, 0) - centre + z(c, 1, r, 0),
                    z(c, 0, r, -1) - centre + z(c, 0, r, 1),
                    z(c, 1, r, 1) - z(c, 1, r, -1) - z(c, -1, r, 1) + z(c, -1, r, -1),
                ];
                for (k, want) in want.into_iter().enumerate() {
                    let on = mask_block[c + HALO] & (1 << k) != 0;
                    let want = if on { want as f32 } else { 0.0 };
                    let got = out[k * pw + c + HALO];
                    assert_eq!(
                        got.to_bits(),
                        want.to_bits(),
                        "{w}x{h} ({c}, {r}) plane {k}"
                    );
                }
            }
        }
    }
}

#[test]
fn the_system_holds_no_kz_for_the_level() {
    // 40 coefficients, 16 data forward rows, 12 weights, 8 diagonal and
    // right-hand side, 4 unknowns, 1 byte of masks: 81 bytes per pixel
    // (82 with the halo at this size); 104 while `K z^k` (12) was stored,
    // the masks took a byte each (3) and the data part kept two planes of
    // zeros (8).
    let (w, h) = (500, 400);
    let level = PyramidLevel {
        geometry: LevelGeometry::new(w, h, w, h, Intrinsics::centred(200.0, w, h)),
        image: std::borrow::Cow::Owned(Grid::filled(w, h, 0.3)),
        confidence: Confidence::from_grid(Grid::filled(w, h, 1.0), Cancel::NEVER).uncancelled(),
        domain: Grid::filled(w, h, true),
    };
    let system = LinearSystem::new(&level, Cancel::NEVER).uncancelled();
    let per_pixel = system.memory_bytes() as f64 / (w * h) as f64;
    assert!(per_pixel < 83.0, "{per_pixel} bytes per pixel");
}

#[test]
fn the_data_part_reaches_no_smoothness_only_entry() {
    // Every forward entry a pair of residual slots lands in is stored by
    // the data part: shared or data-only, never smoothness-only; and the
    // three lists cover the forward half once.
    let mut listed: Vec<usize> = SHARED_FORWARD
        .iter()
        .chain(&DATA_ONLY_FORWARD)
        .chain(&SMOOTH_ONLY_FORWARD)
        .copied()
        .collect();
    listed.sort_unstable();
    assert_eq!(listed, (0..FORWARD.len()).collect::<Vec<_>>());
    for row in KEPT_ENTRY {
        for entry in row {
            if entry != BACKWARD && entry != 0 {
                let k = usize::from(entry) - 1;
                assert!(!SMOOTH_ONLY_FORWARD.contains(&k), "entry {k}");
            }
        }
    }
}
