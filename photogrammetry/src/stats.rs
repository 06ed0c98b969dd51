//! Robust statistics shared by the stages.

/// The median of `values` (the mean of the middle two for an even count); none when empty.
pub fn median(mut values: Vec<f64>) -> Option<f64> {
    values.sort_by(f64::total_cmp);
    let n = values.len();
    (n > 0).then(|| {
        if n % 2 == 1 {
            values[n / 2]
        } else {
            0.5 * (values[n / 2 - 1] + values[n / 2])
        }
    })
}

/// The weighted `q`-quantile (0 to 1) of `(value, weight)` pairs: the first value, in increasing order, at which
/// the cumulative weight reaches `q` of the total; none when empty or weightless.
pub fn weighted_quantile(pairs: &[(f64, f64)], q: f64) -> Option<f64> {
    let mut sorted = pairs.to_vec();
    sorted.sort_by(|a, b| a.0.total_cmp(&b.0));
    let total: f64 = sorted.iter().map(|p| p.1).sum();
    if total.is_nan() || total <= 0.0 {
        return None;
    }
    let mut cumulative = 0.0;
    sorted
        .iter()
        .find(|p| {
            cumulative += p.1;
            cumulative >= q * total
        })
        .or(sorted.last())
        .map(|p| p.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_weighted_quantile_counts_each_value_by_its_weight() {
        let pairs = [(3.0, 1.0), (1.0, 1.0), (2.0, 6.0)];
        assert_eq!(weighted_quantile(&pairs, 0.5), Some(2.0));
        assert_eq!(weighted_quantile(&pairs, 0.1), Some(1.0));
        assert_eq!(weighted_quantile(&pairs, 1.0), Some(3.0));
        assert_eq!(weighted_quantile(&[], 0.5), None);
        assert_eq!(weighted_quantile(&[(1.0, 0.0)], 0.5), None);
    }

    #[test]
    fn the_median_of_odd_and_even_counts_and_of_none() {
        assert_eq!(median(vec![3.0, 1.0, 2.0]), Some(2.0));
        assert_eq!(median(vec![4.0, 1.0, 3.0, 2.0]), Some(2.5));
        assert_eq!(median(Vec::new()), None);
    }
}
