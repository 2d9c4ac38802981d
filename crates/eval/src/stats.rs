//! The statistics every table prints: success-rate intervals and running
//! means with their 95% intervals.

/// The 95% Wilson score interval of a success rate (k successes of n): unlike
/// the normal approximation it is not zero-width at 0 or 1.
pub fn wilson(successes: usize, n: usize) -> (f64, f64) {
    if n == 0 {
        return (f64::NAN, f64::NAN);
    }
    let (n, p, z) = (n as f64, successes as f64 / n as f64, 1.96f64);
    let centre = (p + z * z / (2.0 * n)) / (1.0 + z * z / n);
    let half = z / (1.0 + z * z / n) * (p * (1.0 - p) / n + z * z / (4.0 * n * n)).sqrt();
    ((centre - half).max(0.0), (centre + half).min(1.0))
}

/// Running statistics of one table cell: the count, the sum (added in
/// order, so the mean equals `values.sum() / n` exactly), Welford's sum of
/// squared deviations and the successes (values above 0.5). Memory does not
/// grow with the number of values.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Running {
    /// Values pushed.
    pub n: usize,
    /// Their sum, in push order.
    pub sum: f64,
    welford_mean: f64,
    m2: f64,
    /// Values above 0.5 (success rates).
    pub successes: usize,
}

impl Running {
    /// Adds one value.
    pub fn push(&mut self, v: f64) {
        self.n += 1;
        self.sum += v;
        let delta = v - self.welford_mean;
        self.welford_mean += delta / self.n as f64;
        self.m2 += delta * (v - self.welford_mean);
        if v > 0.5 {
            self.successes += 1;
        }
    }

    /// The mean (NaN before any value).
    pub fn mean(&self) -> f64 {
        if self.n == 0 {
            f64::NAN
        } else {
            self.sum / self.n as f64
        }
    }

    /// Mean and half-width of the 95% interval (normal approximation).
    pub fn mean_ci(&self) -> (f64, f64) {
        let mean = self.mean();
        if self.n < 2 {
            return (mean, if self.n == 1 { 0.0 } else { f64::NAN });
        }
        let var = (self.m2 / (self.n - 1) as f64).max(0.0);
        (mean, 1.96 * (var / self.n as f64).sqrt())
    }
}

/// Mean and half-width of the 95% interval (normal approximation).
pub fn mean_ci(values: &[f64]) -> (f64, f64) {
    let n = values.len() as f64;
    if n == 0.0 {
        return (f64::NAN, f64::NAN);
    }
    let mean = values.iter().sum::<f64>() / n;
    if n < 2.0 {
        return (mean, 0.0);
    }
    let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
    (mean, 1.96 * (var / n).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wilson_intervals_match_the_formula_and_are_not_empty_at_the_ends() {
        // 10 of 10: the normal approximation says 1.00 +- 0.00.
        let (lo, hi) = wilson(10, 10);
        assert!((lo - 0.7225).abs() < 1e-3 && hi == 1.0, "{lo} {hi}");
        let (lo, hi) = wilson(0, 20);
        assert!(lo == 0.0 && (hi - 0.1611).abs() < 1e-3, "{lo} {hi}");
        // 23 of 50 (0.46): [0.3297, 0.5961].
        let (lo, hi) = wilson(23, 50);
        assert!(
            (lo - 0.3297).abs() < 1e-3 && (hi - 0.5961).abs() < 1e-3,
            "{lo} {hi}"
        );
        assert!(wilson(0, 0).0.is_nan());
    }

    #[test]
    fn running_statistics_equal_the_two_pass_ones() {
        let values = [0.25, 1.0, 0.0, 0.75, 0.5, 1.0, 0.125];
        let mut r = Running::default();
        for v in values {
            r.push(v);
        }
        let (m, h) = mean_ci(&values);
        let (rm, rh) = r.mean_ci();
        assert_eq!(rm, m);
        assert!((rh - h).abs() < 1e-12, "{rh} {h}");
        assert_eq!((r.n, r.successes), (7, 3));
        assert!(Running::default().mean_ci().0.is_nan());
        let mut one = Running::default();
        one.push(0.3);
        assert_eq!(one.mean_ci(), (0.3, 0.0));
    }
}
