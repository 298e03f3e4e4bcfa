//! The `[settings]` table of task and problem files: deserialized straight into
//! [`armature_scvx::PtrSettings`] (unknown keys and wrong types are located by the TOML
//! parser), then validated, with an unusable value located at its key.

use std::ops::Range;

use armature_scvx::PtrSettings;
use toml::de::{DeTable, DeValue};

use crate::task::{LocatedError, Source};

/// Checks the settings of a file, locating an unusable value at its key under `[settings]`.
///
/// # Errors
/// The first unusable setting, as `file:line:col: [settings] FIELD …`.
pub fn checked(settings: &PtrSettings, src: Source<'_>) -> Result<PtrSettings, LocatedError> {
    match settings.validate() {
        Ok(()) => Ok(settings.clone()),
        Err(e) => {
            let mut path = vec!["settings"];
            path.extend(e.field.split('.'));
            let at = key_span(src.text, &path).map_or(0, |r| r.start);
            Err(src.error_at(at, format!("[settings] {} {}", e.field, e.reason)))
        }
    }
}

/// The span of the value at `path` (keys from the document's root), or of the deepest key on
/// the path that the document has; `None` when the text does not parse or lacks `path[0]`.
pub fn key_span(text: &str, path: &[&str]) -> Option<Range<usize>> {
    let root = DeTable::parse(text).ok()?;
    let mut table: &DeTable<'_> = root.get_ref();
    let mut found = None;
    for key in path {
        let Some((_, value)) = table.iter().find(|(k, _)| k.get_ref().as_ref() == *key) else {
            break;
        };
        found = Some(value.span());
        match value.get_ref() {
            DeValue::Table(t) => table = t,
            _ => break,
        }
    }
    found
}

/// What a problem-layer error names (`time`, `state "p"`, a dotted setting path such as
/// `discretization.substeps`): the `what` of a bad-input or symbolic error, else empty.
pub fn error_subject(e: &armature_scvx::ProblemError) -> &str {
    use armature_scvx::ProblemError;
    match e {
        ProblemError::Bad { what, .. } | ProblemError::Symbolic { what, .. } => what.as_str(),
        _ => "",
    }
}

/// Where `[settings]` gives the setting a problem-layer error names (`what`, a dotted
/// field path such as `discretization.substeps`), if it does.
pub fn setting_span(text: &str, what: &str) -> Option<usize> {
    let path: Vec<&str> = std::iter::once("settings").chain(what.split('.')).collect();
    key_span(text, &path).filter(|_| has_key(text, &path)).map(|r| r.start)
}

/// Whether the document has a value at `path` (keys from the root).
pub fn has_key(text: &str, path: &[&str]) -> bool {
    let Ok(root) = DeTable::parse(text) else { return false };
    let mut table: &DeTable<'_> = root.get_ref();
    for (i, key) in path.iter().enumerate() {
        let Some((_, value)) = table.iter().find(|(k, _)| k.get_ref().as_ref() == *key) else {
            return false;
        };
        match value.get_ref() {
            _ if i + 1 == path.len() => return true,
            DeValue::Table(t) => table = t,
            _ => return false,
        }
    }
    false
}

#[cfg(test)]
mod tests {
    use super::*;

    const TEXT: &str = "[robot]\nname = \"arm7\"\n\n[settings]\nlam_tr = 2.0\n\n\
                        [settings.subproblem.clarabel]\nmax_iterations = 0\n";

    #[test]
    fn a_key_is_there_or_not() {
        assert!(has_key(TEXT, &["settings", "subproblem", "clarabel", "max_iterations"]));
        assert!(has_key(TEXT, &["settings", "lam_tr"]));
        assert!(!has_key(TEXT, &["settings", "subproblem", "clarabel", "tolerance"]));
        assert!(!has_key(TEXT, &["settings", "lam_tr", "deeper"]));
        assert!(!has_key(TEXT, &["settings", "discretization", "substeps"]));
        assert!(!has_key("not = toml = at all", &["settings"]));
    }

    #[test]
    fn a_key_is_found_at_its_value() {
        let r = key_span(TEXT, &["settings", "lam_tr"]).unwrap();
        assert_eq!(&TEXT[r], "2.0");
        let r = key_span(TEXT, &["settings", "subproblem", "clarabel", "max_iterations"]).unwrap();
        assert_eq!(&TEXT[r], "0");
    }

    #[test]
    fn a_missing_key_falls_back_to_its_deepest_table() {
        let r = key_span(TEXT, &["settings", "subproblem", "interior_point", "tolerance"]);
        assert_eq!(&TEXT[r.unwrap()], "subproblem", "the key in `[settings.subproblem.clarabel]`");
        assert_eq!(key_span(TEXT, &["time"]), None);
        assert_eq!(key_span("[[[", &["settings"]), None);
    }

    #[test]
    fn an_unusable_setting_is_located_at_its_key() {
        let text = "[settings]\nmax_iterations = 3\n\n[settings.subproblem.clarabel]\n\
                    max_iterations = 0\n";
        let settings: PtrSettings =
            toml::from_str::<toml::Table>(text).unwrap()["settings"].clone().try_into().unwrap();
        let e = checked(&settings, Source { name: "t.toml", text }).unwrap_err();
        assert_eq!((e.line, e.column), (5, 18), "{e}");
        assert!(e.message.contains("subproblem.clarabel.max_iterations"), "{e}");
    }
}
