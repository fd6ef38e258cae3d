//! Order statistics of the large sets of values a photograph gives (a value
//! per pixel): the exact k-th smallest, found in parallel by rows, polling a
//! [`Cancel`] per row, without holding the whole set.
//!
//! The values must be non-negative and finite: for those the bit patterns of
//! `f64` sort as the numbers do. A first pass counts the values per bucket of
//! their top 16 bits (sign, exponent and 4 bits of mantissa); a second
//! collects only the bucket that holds the wanted rank and selects in it.
//! The result is the same value a sort of the whole set gives.

use rayon::prelude::*;

use crate::cancel::{Cancel, Cancelled};

/// Top bits of a value that name its bucket.
const BUCKET_BITS: u32 = 16;

/// The bucket of a non-negative finite value.
#[inline]
fn bucket(value: f64) -> usize {
    (value.to_bits() >> (64 - BUCKET_BITS)) as usize
}

/// The `rank(count)`-th smallest (from 0) of the values `row_values(r, out)`
/// pushes onto `out` for rows `0..rows` (non-negative and finite; `count` is
/// how many there are, `rank(count) < count`); `None` when there is no
/// value. Polls `cancel` per row of each of the two passes.
pub fn kth_smallest(
    rows: usize,
    row_values: impl Fn(usize, &mut Vec<f64>) + Sync,
    rank: impl Fn(usize) -> usize,
    cancel: Cancel<'_>,
) -> Result<Option<f64>, Cancelled> {
    // Few enough tasks that their histograms (256 KiB each) stay small.
    let min_rows = rows.div_ceil(32).max(1);
    let counts = (0..rows)
        .into_par_iter()
        .with_min_len(min_rows)
        .fold(
            || (vec![0u32; 1 << BUCKET_BITS], Vec::new()),
            |(mut counts, mut values), r| {
                if !cancel.is_cancelled() {
                    values.clear();
                    row_values(r, &mut values);
                    for &v in &values {
                        counts[bucket(v)] += 1;
                    }
                }
                (counts, values)
            },
        )
        .map(|(counts, _)| counts.into_iter().map(u64::from).collect::<Vec<u64>>())
        .reduce(
            || vec![0u64; 1 << BUCKET_BITS],
            |mut a, b| {
                a.iter_mut().zip(&b).for_each(|(a, b)| *a += b);
                a
            },
        );
    cancel.check()?;
    let total: u64 = counts.iter().sum();
    if total == 0 {
        return Ok(None);
    }
    let wanted = rank(total as usize).min(total as usize - 1) as u64;
    let mut before = 0u64;
    let mut chosen = 0;
    for (b, &n) in counts.iter().enumerate() {
        if before + n > wanted {
            chosen = b;
            break;
        }
        before += n;
    }
    let mut candidates: Vec<f64> = (0..rows)
        .into_par_iter()
        .with_min_len(min_rows)
        .fold(
            || (Vec::new(), Vec::new()),
            |(mut kept, mut values): (Vec<f64>, Vec<f64>), r| {
                if !cancel.is_cancelled() {
                    values.clear();
                    row_values(r, &mut values);
                    kept.extend(values.iter().filter(|&&v| bucket(v) == chosen));
                }
                (kept, values)
            },
        )
        .map(|(kept, _)| kept)
        .reduce(Vec::new, |mut a, mut b| {
            a.append(&mut b);
            a
        });
    cancel.check()?;
    let within = (wanted - before) as usize;
    Ok((within < candidates.len())
        .then(|| *candidates.select_nth_unstable_by(within, f64::total_cmp).1))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The same rank by sorting everything.
    fn by_sorting(values: &[f64], rank: usize) -> f64 {
        let mut sorted = values.to_vec();
        sorted.sort_by(f64::total_cmp);
        sorted[rank]
    }

    #[test]
    fn gives_what_a_full_sort_gives() {
        // Values over many binades, ties, zeros, and rows of any length.
        let rows: Vec<Vec<f64>> = (0..57)
            .map(|r| {
                (0..(r * 7) % 23)
                    .map(|c| {
                        let x = ((r * 31 + c * 17) % 101) as f64;
                        match (r + c) % 5 {
                            0 => 0.0,
                            1 => x * 1e-9,
                            2 => x,
                            3 => 1.0 + x * 1e-12,
                            _ => x * 1e6,
                        }
                    })
                    .collect()
            })
            .collect();
        let all: Vec<f64> = rows.iter().flatten().copied().collect();
        for rank in [0, 1, all.len() / 4, all.len() / 2, all.len() - 1] {
            let got = kth_smallest(
                rows.len(),
                |r, out| out.extend(&rows[r]),
                |_| rank,
                Cancel::NEVER,
            );
            assert_eq!(
                got.map(|v| v.map(f64::to_bits)),
                Ok(Some(by_sorting(&all, rank).to_bits()))
            );
        }
    }

    #[test]
    fn nothing_gives_none_and_a_cancel_gives_cancelled() {
        assert_eq!(
            kth_smallest(10, |_, _| {}, |n| n / 2, Cancel::NEVER),
            Ok(None)
        );
        assert_eq!(
            kth_smallest(
                10,
                |r, out| out.push(r as f64),
                |n| n / 2,
                Cancel::new(&|| true)
            ),
            Err(Cancelled)
        );
    }
}
