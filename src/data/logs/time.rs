//! Exact time stamps: a decimal m·10^e (m an i128), so that stamps like
//! `1733400000.123456789` (epoch seconds) or `8123.456` (controller uptime)
//! are subtracted without rounding before they become f64 seconds.

use std::cmp::Ordering;

/// An exact decimal number m·10^e.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Decimal {
    /// Mantissa m.
    pub mantissa: i128,
    /// Exponent e (power of ten).
    pub exponent: i32,
}

/// Most significant digits kept exactly (i128 holds 38).
const MAX_DIGITS: usize = 36;

/// Parses a decimal number (`-12.5`, `8123.456`, `1.5e3`, `+7`) exactly.
/// Errors (as text) on anything else: no digits, more than 36 significant
/// digits, a bad exponent, `nan`/`inf`, hexadecimal.
pub fn parse_decimal(text: &str) -> std::result::Result<Decimal, String> {
    let s = text.trim();
    let (neg, body) = match s.as_bytes().first() {
        Some(b'-') => (true, &s[1..]),
        Some(b'+') => (false, &s[1..]),
        _ => (false, s),
    };
    let (num, exp_part) = match body.find(['e', 'E']) {
        Some(i) => (&body[..i], Some(&body[i + 1..])),
        None => (body, None),
    };
    let (int, frac) = match num.find('.') {
        Some(i) => (&num[..i], &num[i + 1..]),
        None => (num, ""),
    };
    if int.is_empty() && frac.is_empty() {
        return Err(format!("expected a decimal number, found {text:?}"));
    }
    if !int.bytes().chain(frac.bytes()).all(|b| b.is_ascii_digit()) {
        return Err(format!("expected a decimal number, found {text:?}"));
    }
    let mut exponent: i64 = -(frac.len() as i64);
    if let Some(e) = exp_part {
        let v: i64 = e
            .parse()
            .ok()
            .filter(|v: &i64| v.abs() <= 300)
            .ok_or_else(|| format!("expected a decimal number with an exponent of at most ±300, found {text:?}"))?;
        exponent += v;
    }
    let digits = int.bytes().chain(frac.bytes()).skip_while(|&b| b == b'0');
    let mut mantissa: i128 = 0;
    let mut count = 0usize;
    for b in digits {
        count += 1;
        if count > MAX_DIGITS {
            return Err(format!(
                "{text:?} has more than {MAX_DIGITS} significant digits; time stamps are kept exact up to that"
            ));
        }
        mantissa = mantissa * 10 + i128::from(b - b'0');
    }
    if neg {
        mantissa = -mantissa;
    }
    Ok(Decimal {
        mantissa,
        exponent: exponent as i32,
    })
}

fn pow10(k: u32) -> Option<i128> {
    10i128.checked_pow(k)
}

impl Decimal {
    /// An integer count of units 10^exponent (e.g. nanoseconds: exponent −9).
    pub fn from_int(value: i128, exponent: i32) -> Decimal {
        Decimal { mantissa: value, exponent }
    }

    /// The same number in units 10^`exponent` (which must not exceed this
    /// one's), if it fits.
    fn at(&self, exponent: i32) -> Option<i128> {
        let k = u32::try_from(self.exponent.checked_sub(exponent)?).ok()?;
        self.mantissa.checked_mul(pow10(k)?)
    }

    /// Both numbers in the smaller of the two units, if they fit.
    fn aligned(&self, other: &Decimal) -> Option<(i128, i128, i32)> {
        let e = self.exponent.min(other.exponent);
        Some((self.at(e)?, other.at(e)?, e))
    }

    /// The value as f64 (rounded).
    pub fn to_f64(&self) -> f64 {
        to_f64(self.mantissa, self.exponent)
    }

    /// Exact comparison (through f64 only where the numbers cannot be aligned in an i128).
    pub fn cmp_exact(&self, other: &Decimal) -> Ordering {
        match self.aligned(other) {
            Some((a, b, _)) => a.cmp(&b),
            None => self.to_f64().total_cmp(&other.to_f64()),
        }
    }

    /// (self − t0) in seconds, the subtraction exact, one rounding to f64.
    pub fn seconds_since(&self, t0: &Decimal) -> f64 {
        match self.aligned(t0) {
            Some((a, b, e)) => match a.checked_sub(b) {
                Some(d) => to_f64(d, e),
                None => self.to_f64() - t0.to_f64(),
            },
            None => self.to_f64() - t0.to_f64(),
        }
    }

    /// The number as decimal text (`8123.456`, `-0.001`, `17e3`).
    pub fn text(&self) -> String {
        let neg = self.mantissa < 0;
        let digits = self.mantissa.unsigned_abs().to_string();
        let sign = if neg { "-" } else { "" };
        if self.exponent >= 0 {
            return if self.exponent == 0 || self.mantissa == 0 {
                format!("{sign}{digits}")
            } else {
                format!("{sign}{digits}e{}", self.exponent)
            };
        }
        let k = self.exponent.unsigned_abs() as usize;
        if digits.len() > k {
            let (i, f) = digits.split_at(digits.len() - k);
            format!("{sign}{i}.{f}")
        } else {
            format!("{sign}0.{}{digits}", "0".repeat(k - digits.len()))
        }
    }
}

/// m·10^e as f64: trailing zeros of m are moved into e first, so that an
/// exact quotient (e.g. 5/10³) is rounded once.
fn to_f64(mut m: i128, mut e: i32) -> f64 {
    while e < 0 && m != 0 && m % 10 == 0 {
        m /= 10;
        e += 1;
    }
    let x = m as f64;
    if e >= 0 {
        x * 10f64.powi(e)
    } else if e >= -22 {
        // 10^k is exact in f64 for k ≤ 22: one correctly rounded division
        x / 10f64.powi(-e)
    } else {
        x / 1e22 / 10f64.powi(-e - 22)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_exactly_and_subtracts_without_rounding() {
        let a = parse_decimal("1733400000.123456789").unwrap();
        assert_eq!((a.mantissa, a.exponent), (1733400000123456789, -9));
        let b = parse_decimal("1733400000.128456789").unwrap();
        // as f64 the two stamps differ by a multiple of 2.4e-7 s; exactly by 5 ms
        assert_eq!(b.seconds_since(&a), 0.005);
        assert_eq!(parse_decimal("8123.45").unwrap().seconds_since(&parse_decimal("8123.456").unwrap()), -0.006);
        assert_eq!(parse_decimal("1.5e3").unwrap().to_f64(), 1500.0);
        assert_eq!(parse_decimal("-.5").unwrap().to_f64(), -0.5);
        assert_eq!(parse_decimal("8123.456").unwrap().text(), "8123.456");
        assert_eq!(parse_decimal("-0.001").unwrap().text(), "-0.001");
        for bad in ["", ".", "nan", "inf", "1,5", "0x10", "1e", "1e999", "--1", "1.2.3", "١"] {
            assert!(parse_decimal(bad).is_err(), "{bad:?}");
        }
        assert!(parse_decimal(&"9".repeat(37)).is_err());
        assert!(parse_decimal(&format!("0.{}1", "0".repeat(60))).is_ok());
    }

    #[test]
    fn ordering_is_exact_where_f64_is_not() {
        let a = parse_decimal("1733400000.123456789").unwrap();
        let b = parse_decimal("1733400000.123456790").unwrap();
        assert_eq!(a.to_f64(), b.to_f64());
        assert_eq!(a.cmp_exact(&b), Ordering::Less);
        assert_eq!(b.cmp_exact(&a), Ordering::Greater);
        assert_eq!(a.cmp_exact(&a), Ordering::Equal);
        // far apart exponents fall back to f64 without panicking
        let big = parse_decimal("1e300").unwrap();
        let small = parse_decimal("1e-300").unwrap();
        assert_eq!(big.cmp_exact(&small), Ordering::Greater);
        assert!(big.seconds_since(&small) > 0.0);
    }
}
