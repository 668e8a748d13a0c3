//! Whole numbers as JSON Schema reads them: `39` and `39.0` are the same integer, so every
//! integer field of a scene accepts a number with no fractional part in either spelling (some
//! clients write every number as a float). `39.5`, a negative number and one beyond the range
//! are refused at the field's pointer with the value and the range in the reason.

use std::fmt;

use serde::de::{self, Deserialize, Deserializer, Unexpected, Visitor};

/// A count or an index read from any JSON number with no fractional part.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Whole(usize);

/// One past the largest `usize`, as a float: the first float that does not fit.
const PAST_USIZE: f64 = usize::MAX as f64 + 1.0;

impl<'de> Deserialize<'de> for Whole {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        deserializer.deserialize_u64(WholeVisitor)
    }
}

struct WholeVisitor;

impl Visitor<'_> for WholeVisitor {
    type Value = Whole;

    fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "a whole number from 0 to {}", usize::MAX)
    }

    fn visit_u64<E: de::Error>(self, value: u64) -> Result<Whole, E> {
        usize::try_from(value).map(Whole).map_err(|_| E::invalid_value(Unexpected::Unsigned(value), &self))
    }

    fn visit_i64<E: de::Error>(self, value: i64) -> Result<Whole, E> {
        match u64::try_from(value) {
            Ok(value) => self.visit_u64(value),
            Err(_) => Err(E::invalid_value(Unexpected::Signed(value), &self)),
        }
    }

    fn visit_f64<E: de::Error>(self, value: f64) -> Result<Whole, E> {
        // Comparisons with NaN are false, so a NaN is refused too.
        if value.fract() == 0.0 && (0.0..PAST_USIZE).contains(&value) {
            Ok(Whole(value as usize))
        } else {
            Err(E::invalid_value(Unexpected::Float(value), &self))
        }
    }
}

/// A whole number (`#[serde(deserialize_with = "whole::one")]`).
pub(super) fn one<'de, D: Deserializer<'de>>(deserializer: D) -> Result<usize, D::Error> {
    Whole::deserialize(deserializer).map(|w| w.0)
}

/// A fixed number of whole numbers, such as a resolution.
pub(super) fn array<'de, D, const N: usize>(deserializer: D) -> Result<[usize; N], D::Error>
where
    D: Deserializer<'de>,
    [Whole; N]: Deserialize<'de>,
{
    <[Whole; N]>::deserialize(deserializer).map(|values| values.map(|w| w.0))
}

/// A list of whole numbers, such as particle indices.
pub(super) fn list<'de, D: Deserializer<'de>>(deserializer: D) -> Result<Vec<usize>, D::Error> {
    Vec::<Whole>::deserialize(deserializer).map(|values| values.into_iter().map(|w| w.0).collect())
}

/// A list of fixed-size groups of whole numbers, such as grid pins `[i, j]`.
pub(super) fn list_of_arrays<'de, D, const N: usize>(deserializer: D) -> Result<Vec<[usize; N]>, D::Error>
where
    D: Deserializer<'de>,
    [Whole; N]: Deserialize<'de>,
{
    Vec::<[Whole; N]>::deserialize(deserializer)
        .map(|groups| groups.into_iter().map(|group| group.map(|w| w.0)).collect())
}

#[cfg(test)]
mod tests {
    use serde_json::json;

    use super::*;

    fn read(value: serde_json::Value) -> Result<usize, String> {
        one(value).map_err(|e| e.to_string())
    }

    #[test]
    fn integral_floats_are_whole_numbers_and_others_are_refused_with_the_value() {
        assert_eq!(read(json!(39)), Ok(39));
        assert_eq!(read(json!(39.0)), Ok(39));
        assert_eq!(read(json!(0.0)), Ok(0));
        assert_eq!(read(json!(-0.0)), Ok(0));
        assert_eq!(read(json!(1e15)), Ok(1_000_000_000_000_000));
        let range = format!("expected a whole number from 0 to {}", usize::MAX);
        assert_eq!(read(json!(39.5)), Err(format!("invalid value: floating point `39.5`, {range}")));
        assert_eq!(read(json!(-3)), Err(format!("invalid value: integer `-3`, {range}")));
        assert_eq!(read(json!(-3.0)), Err(format!("invalid value: floating point `-3.0`, {range}")));
        assert_eq!(read(json!(1e20)), Err(format!("invalid value: floating point `1e+20`, {range}")));
        assert_eq!(read(json!("4")), Err(format!("invalid type: string \"4\", {range}")));
        assert_eq!(array::<_, 2>(json!([4.0, 5])).map_err(|e| e.to_string()), Ok([4, 5]));
        assert_eq!(list(json!([1.0, 2])).map_err(|e| e.to_string()), Ok(vec![1, 2]));
        assert_eq!(
            list_of_arrays::<_, 3>(json!([[1.0, 2, 3e0]])).map_err(|e| e.to_string()),
            Ok(vec![[1, 2, 3]])
        );
    }
}
