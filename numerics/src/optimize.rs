//! One-dimensional minimisation.

/// Golden-section search for a minimum of `f` on `[a, b]`: `iterations` shrinkings of the
/// bracket by 0.618 each; returns the final bracket. `f` is assumed unimodal on `[a, b]`;
/// otherwise the bracket closes on one local minimum.
pub fn golden_section(f: impl Fn(f64) -> f64, a: f64, b: f64, iterations: usize) -> (f64, f64) {
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let (mut a, mut b) = (a, b);
    let (mut c, mut d) = (b - g * (b - a), a + g * (b - a));
    let (mut fc, mut fd) = (f(c), f(d));
    for _ in 0..iterations {
        if fc < fd {
            b = d;
            d = c;
            fd = fc;
            c = b - g * (b - a);
            fc = f(c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + g * (b - a);
            fd = f(d);
        }
    }
    (a, b)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_the_minimum_of_a_parabola_and_of_an_asymmetric_function() {
        let (a, b) = golden_section(|x| (x - 0.3).powi(2), -2.0, 5.0, 60);
        assert!((0.5 * (a + b) - 0.3).abs() < 1e-9 && b - a < 1e-9);
        // A kink: |x − 1.7| + 0.1 x² has its minimum at 1.7.
        let (a, b) = golden_section(|x| (x - 1.7).abs() + 0.1 * x * x, 0.0, 4.0, 60);
        assert!((0.5 * (a + b) - 1.7).abs() < 1e-8);
        // At the end of the bracket when the minimum lies outside it.
        let (_, b) = golden_section(|x| x, 1.0, 2.0, 60);
        assert!((b - 1.0).abs() < 1e-9);
    }
}
