//! The memory guard: an estimate of a job's peak memory from its image size,
//! compared with the memory the machine has free before any large
//! allocation, so an oversized image is refused with a message instead of
//! driving the machine into swap or the out-of-memory killer.
//!
//! The per-pixel figures are measured peaks (resident set size of a release
//! build, `/usr/bin/time -v`) with a margin; docs/guarantees.md lists them. The free memory is Linux's
//! `MemAvailable` and, inside a container, the cgroup's remaining limit;
//! `SFS_STUDIO_MEMORY_MB` replaces it (0 turns the guard off). Elsewhere
//! the guard is off unless that variable is set.

use std::fs;

/// Peak bytes per pixel of a solve at its working size (every pyramid
/// level, the Gauss-Newton system, the fast-marching start). Measured as the
/// whole `solve` process's peak resident set, outputs included: about 195
/// on the pyramid path (a light beside the lens, 1024x1024) and 130 with the
/// fast-marching start (1920x1080); 300 keeps a margin of a half over the
/// larger (it was 400 when the solve itself needed 270 to 350).
pub const SOLVE_BYTES_PER_PIXEL: u64 = 300;
/// Peak bytes per pixel of the full-size photograph while it is read and
/// area-averaged to the working size: the decoder's buffer (1 for 8-bit
/// grey up to 16 for float RGBA) and the linear grey copy (8); measured 9
/// for a 100-megapixel 8-bit grey PNG.
pub const LOAD_BYTES_PER_PIXEL: u64 = 24;
/// Peak bytes per pixel of `synth` (the rendered image, its depth, mask,
/// noise and the PNG encoders; measured 28 to 32 at 2048x2048).
pub const SYNTH_BYTES_PER_PIXEL: u64 = 48;
/// The program's own memory besides the image (code, mesh, buffers).
pub const BASE_BYTES: u64 = 64 << 20;
/// The environment variable that sets the memory the guard allows, in MiB
/// (0: no guard).
pub const LIMIT_VARIABLE: &str = "SFS_STUDIO_MEMORY_MB";

/// A job that would not fit the memory there is, or a limit that is not one.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MemoryError {
    /// The job would need more than the memory allowed.
    #[error(
        "{what} would need about {} but only {} is available{}; {way_out}",
        format_bytes(*.estimate_bytes),
        format_bytes(*.available_bytes),
        if *.from_variable { " (set by SFS_STUDIO_MEMORY_MB)" } else { "" }
    )]
    TooLarge {
        /// The job, naming its size (e.g. "solving 10000x10000 pixels").
        what: String,
        /// Estimated peak.
        estimate_bytes: u64,
        /// Memory available.
        available_bytes: u64,
        /// The limit came from [`LIMIT_VARIABLE`].
        from_variable: bool,
        /// What the user can do.
        way_out: String,
    },
    /// [`LIMIT_VARIABLE`] is set to something that is not a whole number of
    /// MiB.
    #[error(
        "SFS_STUDIO_MEMORY_MB={0:?} is not a memory limit: give a whole number of MiB (0 turns \
         the memory guard off) or unset it"
    )]
    BadLimit(String),
}

/// Estimated peak bytes of solving a photograph of `full` pixels at the
/// working size `working` (both `(width, height)`), `images` of them summed.
/// `pyramid_factor`: the pyramid's total pixels over the working size's
/// (about 5.3 at the default eta 0.9, up to 50 at eta 0.99); beyond the
/// default's, each further level pixel costs [`LEVEL_BYTES_PER_PIXEL`].
pub fn solve_estimate(
    full: (usize, usize),
    working: (usize, usize),
    images: usize,
    pyramid_factor: f64,
) -> u64 {
    let extra_levels = (pyramid_factor - DEFAULT_PYRAMID_FACTOR).max(0.0);
    let full_px = (full.0 as u64).saturating_mul(full.1 as u64);
    let working_px = (working.0 as u64).saturating_mul(working.1 as u64);
    let load = full_px.saturating_mul(LOAD_BYTES_PER_PIXEL);
    // Summed images keep one working-size sum besides the image being read.
    let sum = working_px.saturating_mul(8 * images.saturating_sub(1).min(1) as u64);
    let levels = (working_px as f64 * extra_levels * LEVEL_BYTES_PER_PIXEL as f64) as u64;
    BASE_BYTES
        .saturating_add(load)
        .saturating_add(sum)
        .saturating_add(levels)
        .saturating_add(working_px.saturating_mul(SOLVE_BYTES_PER_PIXEL))
}

/// The pyramid factor [`SOLVE_BYTES_PER_PIXEL`] was measured at (eta 0.9).
pub const DEFAULT_PYRAMID_FACTOR: f64 = 5.3;
/// Bytes per pixel of a pyramid level (image, confidence, domain, kept for
/// the whole solve).
pub const LEVEL_BYTES_PER_PIXEL: u64 = 24;

/// The largest working size (longest side, a multiple of 100 px) at which
/// solving a photograph of `full` pixels fits in `allowed` bytes; `None`
/// when even reading it does not fit.
pub fn largest_fitting_side(
    full: (usize, usize),
    images: usize,
    pyramid_factor: f64,
    allowed: u64,
) -> Option<usize> {
    let longest = full.0.max(full.1);
    (1..=longest / 100).rev().map(|k| k * 100).find(|&side| {
        let working = crate::resample::working_size(full.0, full.1, Some(side));
        solve_estimate(full, working, images, pyramid_factor) <= allowed
    })
}

/// What a solve of a photograph must be told before it starts.
pub struct SolvePlan<'a> {
    /// The job as the message names it (file, sizes).
    pub what: String,
    /// The photograph's `(width, height)`.
    pub full: (usize, usize),
    /// The working size it is solved at.
    pub working: (usize, usize),
    /// Photographs summed.
    pub images: usize,
    /// The pyramid's total pixels over the working size's.
    pub pyramid_factor: f64,
    /// The way out, given a working size (longest side) that would fit.
    pub smaller: &'a dyn Fn(usize) -> String,
    /// The way out when no working size fits.
    pub otherwise: &'a str,
}

/// Refuses a solve that would not fit the allowance ([`allowance`]), with
/// the largest working size that would.
pub fn check_solve(plan: &SolvePlan<'_>) -> Result<(), MemoryError> {
    let estimate = solve_estimate(plan.full, plan.working, plan.images, plan.pyramid_factor);
    let (allowed, from_variable) = allowance()?;
    let way_out = allowed
        .and_then(|a| largest_fitting_side(plan.full, plan.images, plan.pyramid_factor, a))
        .map_or_else(|| plan.otherwise.to_string(), |side| (plan.smaller)(side));
    check_against(&plan.what, estimate, allowed, from_variable, &way_out)
}

/// Estimated peak bytes of `synth` at `size`.
pub fn synth_estimate(size: (usize, usize)) -> u64 {
    let px = (size.0 as u64).saturating_mul(size.1 as u64);
    BASE_BYTES.saturating_add(px.saturating_mul(SYNTH_BYTES_PER_PIXEL))
}

/// The memory a job may use: [`LIMIT_VARIABLE`] when set (`None` for 0:
/// no guard), else what the system reports free. The flag says whether the
/// variable decided.
///
/// # Errors
/// [`MemoryError::BadLimit`] when the variable is set to anything but a
/// whole number of MiB (it is never silently ignored).
pub fn allowance() -> Result<(Option<u64>, bool), MemoryError> {
    match std::env::var(LIMIT_VARIABLE) {
        Ok(text) => limit_from_variable(&text).map(|limit| (limit, true)),
        Err(std::env::VarError::NotUnicode(text)) => {
            Err(MemoryError::BadLimit(text.to_string_lossy().into_owned()))
        }
        Err(std::env::VarError::NotPresent) => Ok((available(), false)),
    }
}

/// The limit [`LIMIT_VARIABLE`]'s `text` sets, in bytes (`None`: 0, no
/// guard).
fn limit_from_variable(text: &str) -> Result<Option<u64>, MemoryError> {
    let mib = text
        .trim()
        .parse::<u64>()
        .map_err(|_| MemoryError::BadLimit(text.to_string()))?;
    Ok((mib > 0).then(|| mib.saturating_mul(1 << 20)))
}

/// Memory the system can give this process now: `MemAvailable` from
/// `/proc/meminfo`, lowered to the cgroup's remaining limit where there is
/// one; `None` where neither can be read.
pub fn available() -> Option<u64> {
    let meminfo = fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|text| meminfo_available(&text));
    let cgroup = cgroup_remaining();
    match (meminfo, cgroup) {
        (Some(a), Some(b)) => Some(a.min(b)),
        (a, b) => a.or(b),
    }
}

/// `MemAvailable` (in bytes) from the text of `/proc/meminfo`.
fn meminfo_available(text: &str) -> Option<u64> {
    proc_kib(text, "MemAvailable").map(|kib| kib.saturating_mul(1024))
}

/// The number of the `KEY: N kB` line of a Linux `/proc` file's text
/// (`/proc/meminfo`, `/proc/self/status`), in KiB. `key` is the field's
/// whole name without its colon (`MemAvailable`, `VmHWM`): a longer name
/// that starts with it does not match. `None` when the line is missing or
/// its value is not a whole number of kB.
pub fn proc_kib(text: &str, key: &str) -> Option<u64> {
    text.lines().find_map(|line| {
        let (name, value) = line.split_once(':')?;
        if name != key {
            return None;
        }
        let mut words = value.split_whitespace();
        let kib = words.next()?.parse().ok()?;
        (words.next() == Some("kB")).then_some(kib)
    })
}

/// The `KEY: N kB` field `key` of the Linux `/proc` file at `path`, in MiB
/// (see [`proc_kib`]): e.g. `proc_mib("/proc/self/status", "VmHWM")` is the
/// process's peak resident set, `proc_mib("/proc/meminfo", "MemTotal")` the
/// machine's memory. `None` where the file or the field cannot be read (not
/// Linux).
pub fn proc_mib(path: &str, key: &str) -> Option<f64> {
    let text = fs::read_to_string(path).ok()?;
    proc_kib(&text, key).map(|kib| kib as f64 / 1024.0)
}

/// The cgroup v2 limit minus the usage, when a limit is set; the usage
/// without the inactive page cache, which the kernel reclaims on demand.
fn cgroup_remaining() -> Option<u64> {
    let max = fs::read_to_string("/sys/fs/cgroup/memory.max").ok()?;
    let max: u64 = max.trim().parse().ok()?; // "max": no limit
    let current: u64 = fs::read_to_string("/sys/fs/cgroup/memory.current")
        .ok()?
        .trim()
        .parse()
        .ok()?;
    let reclaimable = fs::read_to_string("/sys/fs/cgroup/memory.stat")
        .ok()
        .and_then(|text| stat_value(&text, "inactive_file"))
        .unwrap_or(0);
    Some(max.saturating_sub(current.saturating_sub(reclaimable)))
}

/// The value of `key` in a cgroup `memory.stat` text.
fn stat_value(text: &str, key: &str) -> Option<u64> {
    text.lines()
        .find_map(|l| l.strip_prefix(key)?.strip_prefix(' ')?.trim().parse().ok())
}

/// Refuses a job whose `estimate_bytes` exceeds the allowance
/// ([`allowance`]); `what` names the job and its size, `way_out` what to do.
pub fn check(what: &str, estimate_bytes: u64, way_out: &str) -> Result<(), MemoryError> {
    let (allowed, from_variable) = allowance()?;
    check_against(what, estimate_bytes, allowed, from_variable, way_out)
}

/// [`check`] against a given allowance (`None`: no guard).
pub fn check_against(
    what: &str,
    estimate_bytes: u64,
    allowed: Option<u64>,
    from_variable: bool,
    way_out: &str,
) -> Result<(), MemoryError> {
    match allowed {
        Some(available_bytes) if estimate_bytes > available_bytes => Err(MemoryError::TooLarge {
            what: what.to_string(),
            estimate_bytes,
            available_bytes,
            from_variable,
            way_out: way_out.to_string(),
        }),
        _ => Ok(()),
    }
}

/// Allocations of at least this size get pages of their own from the
/// kernel (glibc's `M_MMAP_THRESHOLD`), returned to it when freed.
pub const UNPOOLED_ALLOCATION_BYTES: usize = 1 << 20;

/// Makes the allocator return every freed buffer of at least
/// [`UNPOOLED_ALLOCATION_BYTES`] to the kernel at once; called by the photo
/// pipeline and the solver before their first large allocation (once per
/// process; a no-op off glibc).
///
/// By default glibc raises that threshold to the size of the largest
/// mapped buffer freed so far (up to 32 MiB): after the photograph's
/// decoding buffer or fast marching's work arrays were freed, the solver's
/// full-size grids of a 1920x1080 photograph (2 to 17 MB) were carved from
/// the heap, and their freed holes stayed resident beside the linear
/// system allocated next: the whole process peaked at 172 to 194 bytes per
/// pixel where its live buffers were 151 (docs/speed.md).
pub fn return_large_frees_to_the_system() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(set_mmap_threshold);
}

#[cfg(all(target_os = "linux", target_env = "gnu"))]
fn set_mmap_threshold() {
    use std::ffi::c_int;
    unsafe extern "C" {
        fn mallopt(param: c_int, value: c_int) -> c_int;
    }
    /// glibc's `M_MMAP_THRESHOLD` (malloc.h).
    const M_MMAP_THRESHOLD: c_int = -3;
    let bytes = c_int::try_from(UNPOOLED_ALLOCATION_BYTES).unwrap_or(c_int::MAX);
    // SAFETY: `mallopt` takes two integers and only changes the allocator's
    // settings (under its own lock); setting the threshold fixes it (glibc's
    // dynamic adjustment stops), which is the point. Its result (0 on a value
    // out of range) leaves the default behaviour: nothing to undo.
    unsafe {
        mallopt(M_MMAP_THRESHOLD, bytes);
    }
}

#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
fn set_mmap_threshold() {}

/// Bytes in MiB or GiB, one decimal.
pub fn format_bytes(bytes: u64) -> String {
    let mib = bytes as f64 / f64::from(1u32 << 20);
    if mib >= 1024.0 {
        format!("{:.1} GiB", mib / 1024.0)
    } else {
        format!("{mib:.0} MiB")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn estimates_grow_with_the_pixels_and_refuse_what_does_not_fit() {
        let small = solve_estimate((256, 256), (256, 256), 1, 5.3);
        let large = solve_estimate((10_000, 10_000), (10_000, 10_000), 1, 5.3);
        assert!(large > 1000 * (small - BASE_BYTES));
        // Working at a smaller size costs the full size only while it is
        // read: the rest is the working size's solve.
        let reduced = solve_estimate((10_000, 10_000), (2000, 2000), 1, 5.3);
        let at_working = solve_estimate((2000, 2000), (2000, 2000), 1, 5.3);
        assert_eq!(
            reduced - at_working,
            (10_000 * 10_000 - 2000 * 2000) * LOAD_BYTES_PER_PIXEL
        );
        let e = check_against(
            "solving 10000x10000 pixels",
            large,
            Some(8 << 30),
            false,
            "use --max-side",
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("10000x10000") && e.contains("only 8.0 GiB is available"),
            "{e}"
        );
        assert!(e.contains("--max-side"), "{e}");
        assert!(check_against("x", small, Some(8 << 30), false, "").is_ok());
        let side = largest_fitting_side((10_000, 10_000), 1, 5.3, 8 << 30).unwrap();
        let working = crate::resample::working_size(10_000, 10_000, Some(side));
        assert!(solve_estimate((10_000, 10_000), working, 1, 5.3) <= 8 << 30);
        let bigger = crate::resample::working_size(10_000, 10_000, Some(side + 100));
        assert!(solve_estimate((10_000, 10_000), bigger, 1, 5.3) > 8 << 30);
        assert_eq!(
            largest_fitting_side((10_000, 10_000), 1, 5.3, 1 << 20),
            None
        );
        // A finer pyramid (eta near 0.99) costs more.
        assert!(solve_estimate((2000, 2000), (2000, 2000), 1, 50.0) > 2 * (large / 25));
        assert!(check_against("x", u64::MAX, None, true, "").is_ok());
        assert_eq!(synth_estimate((usize::MAX, usize::MAX)), u64::MAX);
    }

    #[test]
    fn a_limit_that_is_not_a_whole_number_of_mib_is_refused_by_name() {
        assert_eq!(limit_from_variable("0"), Ok(None));
        assert_eq!(limit_from_variable(" 2 "), Ok(Some(2 << 20)));
        for bad in ["abc", "-5", "1.5", ""] {
            let error = limit_from_variable(bad).expect_err(bad).to_string();
            assert!(
                error.contains("SFS_STUDIO_MEMORY_MB") && error.contains(&format!("{bad:?}")),
                "{error}"
            );
        }
    }

    #[test]
    fn meminfo_is_read_in_kib() {
        let text = "MemTotal:       24000000 kB\nMemAvailable:    1000 kB\n";
        assert_eq!(meminfo_available(text), Some(1_024_000));
        assert_eq!(meminfo_available("nothing"), None);
        let status = "VmPeak:\t  20000 kB\nVmHWM:\t    3072 kB\nVmHWMx:\t 1 kB\nThreads:\t4\n";
        assert_eq!(proc_kib(status, "VmHWM"), Some(3072));
        // The whole name, not a prefix; only values in kB.
        assert_eq!(proc_kib(status, "VmHW"), None);
        assert_eq!(proc_kib(status, "Threads"), None);
        assert_eq!(proc_kib("VmHWM: many kB", "VmHWM"), None);
        // This process has a peak resident set on Linux.
        if cfg!(target_os = "linux") {
            let peak = proc_mib("/proc/self/status", "VmHWM").expect("VmHWM");
            assert!(peak > 0.0, "{peak}");
        }
        assert_eq!(proc_mib("/no/such/file", "VmHWM"), None);
        let stat = "active_file 5\ninactive_file 4096\ninactive_anon 7\n";
        assert_eq!(stat_value(stat, "inactive_file"), Some(4096));
        assert_eq!(stat_value(stat, "file"), None);
    }
}
