//! The paper's own figures (Maurer et al., GCPR 2015, Tables 1-3), one
//! row a scene: read by the report beside the measured numbers and by the
//! Table 1 like-for-like part. Depends on nothing in the bench.

/// The paper's figures for one scene (Tables 1-3; NaN: not reported).
pub(super) struct Paper {
    /// `[Vogel, Ju, ours]` RSE and RIE on clean images.
    pub(super) clean_rse: [f64; 3],
    pub(super) clean_rie: [f64; 3],
    /// The same on noisy images.
    pub(super) noisy_rse: [f64; 3],
    pub(super) noisy_rie: [f64; 3],
    /// Table 2: `[Vogel pre, Vogel post, ours pre, ours post]`.
    pub(super) processed_rse: [f64; 4],
    /// Table 3 runtimes, seconds: `[Vogel, Ju, ours]`.
    pub(super) seconds: [f64; 3],
}

/// The paper's Tables 1-3, a row a scene (NaN: not reported).
#[rustfmt::skip]
const PAPER: [(&str, Paper); 5] = [
    ("sombrero", Paper { clean_rse: [0.00301, 0.00318, 0.00768], clean_rie: [0.00495, 0.00209, 0.00925], noisy_rse: [0.19530, 0.05118, 0.01542], noisy_rie: [0.27254, 0.13239, 0.03851], processed_rse: [0.02008, 0.19197, 0.01741, 0.01538], seconds: [1.0, 29113.0, 17.0] }),
    ("bunny",    Paper { clean_rse: [0.00266, 0.00439, 0.00928], clean_rie: [0.00154, 0.00007, 0.00327], noisy_rse: [0.10973, 0.03235, 0.01359], noisy_rie: [0.17347, 0.15279, 0.12285], processed_rse: [0.01434, 0.06164, 0.01470, 0.01357], seconds: [1.0, 23969.0, 11.0] }),
    ("dragon",   Paper { clean_rse: [0.00422, 0.01376, 0.02904], clean_rie: [0.00255, 0.00028, 0.02333], noisy_rse: [0.12240, 0.05395, 0.03391], noisy_rie: [0.19409, 0.18767, 0.17732], processed_rse: [0.04623, 0.08226, 0.03322, 0.03390], seconds: [1.0, 25350.0, 12.0] }),
    ("suzanne",  Paper { clean_rse: [0.00253, 0.00251, 0.00696], clean_rie: [0.00082, 0.00002, 0.00224], noisy_rse: [0.12134, 0.01256, 0.00826], noisy_rie: [0.16783, 0.14302, 0.12038], processed_rse: [0.01245, 0.06169, 0.00917, 0.00824], seconds: [2.0, 48395.0, 21.0] }),
    ("highres",  Paper { clean_rse: [0.01593, f64::NAN, 0.02930], clean_rie: [0.00067, f64::NAN, 0.03414], noisy_rse: [f64::NAN; 3],               noisy_rie: [f64::NAN; 3],               processed_rse: [f64::NAN; 4],                       seconds: [33.0, f64::NAN, 340.0] }),
];

/// The paper's figures for `scene` (`None`: a scene the paper did not have).
pub(super) fn paper(scene: &str) -> Option<&'static Paper> {
    PAPER
        .iter()
        .find(|(name, _)| *name == scene)
        .map(|(_, figures)| figures)
}

/// The paper's RSE of its own method on `scene`, clean or `noisy` (Table 1;
/// `None`: a scene or condition the paper did not report).
pub(super) fn paper_rse(scene: &str, noisy: bool) -> Option<f64> {
    let p = paper(scene)?;
    let rse = if noisy {
        p.noisy_rse[2]
    } else {
        p.clean_rse[2]
    };
    (!rse.is_nan()).then_some(rse)
}
