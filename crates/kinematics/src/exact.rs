//! Exact-length arrays for serde: `[T; N]` fields that refuse a longer (or shorter) list
//! instead of taking its first `N` entries, which serde's own arrays do with some formats
//! (TOML among them). Use as `#[serde(deserialize_with = "armature_kinematics::exact::array")]`.

use serde::de::{Deserialize, Deserializer, Error};

/// Deserializes exactly `N` values.
///
/// # Errors
/// The format's error for a wrong entry, or an invalid length naming `N`.
///
/// # Example
/// ```
/// #[derive(serde::Deserialize)]
/// struct P {
///     #[serde(deserialize_with = "armature_kinematics::exact::array")]
///     position: [f64; 3],
/// }
/// assert!(toml::from_str::<P>("position = [1.0, 2.0, 3.0]").is_ok());
/// let e = toml::from_str::<P>("position = [1.0, 2.0, 3.0, 4.0]").err().unwrap();
/// assert!(e.to_string().contains("exactly 3 values"), "{e}");
/// ```
pub fn array<'de, D, T, const N: usize>(d: D) -> Result<[T; N], D::Error>
where
    D: Deserializer<'de>,
    T: Deserialize<'de>,
{
    exact(Vec::<T>::deserialize(d)?)
}

/// [`array()`] for an optional field (use with `#[serde(default)]`).
///
/// # Errors
/// As [`array()`].
pub fn optional<'de, D, T, const N: usize>(d: D) -> Result<Option<[T; N]>, D::Error>
where
    D: Deserializer<'de>,
    T: Deserialize<'de>,
{
    Option::<Vec<T>>::deserialize(d)?.map(exact).transpose()
}

/// `v` as an array of exactly `N`.
///
/// # Errors
/// An invalid length naming `N`.
pub fn exact<E: Error, T, const N: usize>(v: Vec<T>) -> Result<[T; N], E> {
    let len = v.len();
    v.try_into().map_err(|_| E::invalid_length(len, &format!("exactly {N} values").as_str()))
}
