//! From a sweep document to its variants: pointers checked, combinations made, each validated.

use serde_json::{Map, Value};

use super::{Sweep, SweepError, Variant};
use crate::scene::{FieldError, Scene};

pub(super) fn expand(document: Value, max_variants: u64) -> Result<Sweep, SweepError> {
    let invalid = |pointer: &str, detail: String| SweepError::Invalid(vec![FieldError::new(pointer, detail)]);
    let Value::Object(mut document) = document else {
        return Err(invalid("", "a sweep is a JSON object with `scene` and `vary`".into()));
    };
    for key in document.keys() {
        if !["scene", "vary", "reference"].contains(&key.as_str()) {
            return Err(invalid(
                &format!("/{}", escape(key)),
                format!("unknown field `{key}`: expected `scene`, `vary` or `reference`"),
            ));
        }
    }
    let base = document.remove("scene").ok_or_else(|| invalid("/scene", "missing: the base scene".into()))?;
    if !base.is_object() {
        return Err(invalid("/scene", "must be a scene object".into()));
    }
    let vary = match document.remove("vary") {
        None => Map::new(),
        Some(Value::Object(vary)) => vary,
        Some(_) => return Err(invalid("/vary", "must map JSON Pointers to lists of values".into())),
    };

    let mut pointers = Vec::new();
    let mut value_lists = Vec::new();
    let mut errors = Vec::new();
    for (pointer, values) in vary {
        let at = format!("/vary/{}", escape(&pointer));
        match values {
            Value::Array(values) if !values.is_empty() => {
                if let Err(detail) = set(&mut base.clone(), &pointer, Value::Null) {
                    errors.push(FieldError::new(&at, detail));
                }
                pointers.push(pointer);
                value_lists.push(values);
            }
            _ => errors.push(FieldError::new(&at, "must be a non-empty list of values")),
        }
    }
    if !errors.is_empty() {
        return Err(SweepError::Invalid(errors));
    }
    let count = value_lists.iter().fold(1u64, |n, list| n.saturating_mul(list.len() as u64));
    if count > max_variants {
        return Err(SweepError::TooManyVariants { variants: count, limit: max_variants });
    }

    let mut variants = Vec::with_capacity(count as usize);
    for index in 0..count {
        let mut rest = index;
        let mut choice = vec![0usize; value_lists.len()];
        for (slot, list) in value_lists.iter().enumerate().rev() {
            choice[slot] = (rest % list.len() as u64) as usize;
            rest /= list.len() as u64;
        }
        let mut scene = base.clone();
        let mut values = Vec::with_capacity(pointers.len());
        for (slot, pointer) in pointers.iter().enumerate() {
            let value = value_lists[slot][choice[slot]].clone();
            set(&mut scene, pointer, value.clone()).expect("every pointer was checked above");
            values.push(value);
        }
        match Scene::from_value(scene.clone()) {
            Ok(parsed) => variants.push(Variant { values, scene: parsed, document: scene }),
            Err(e) => {
                let culprits: Vec<String> =
                    pointers.iter().zip(&choice).map(|(p, &c)| format!("/vary/{}/{c}", escape(p))).collect();
                for problem in scene_problems(&e) {
                    let at = culprits
                        .iter()
                        .zip(&pointers)
                        .find(|(_, p)| {
                            problem.pointer == **p || problem.pointer.starts_with(&format!("{p}/"))
                        })
                        .map_or_else(|| "/scene".to_string(), |(c, _)| c.clone());
                    errors.push(FieldError::new(
                        at,
                        format!("{}: {}", display_pointer(&problem.pointer), problem.detail),
                    ));
                }
                if errors.len() >= 20 {
                    break;
                }
            }
        }
    }
    if !errors.is_empty() {
        let mut unique: Vec<FieldError> = Vec::new();
        for e in errors {
            if !unique.contains(&e) {
                unique.push(e);
            }
        }
        return Err(SweepError::Invalid(unique));
    }

    let reference = match document.remove("reference") {
        None | Some(Value::Null) => None,
        Some(patch @ Value::Object(_)) => {
            let mut scene = base.clone();
            merge_patch(&mut scene, patch);
            let document = scene.clone();
            let scene = Scene::from_value(scene).map_err(|e| {
                SweepError::Invalid(
                    scene_problems(&e)
                        .into_iter()
                        .map(|p| {
                            FieldError::new(
                                "/reference",
                                format!("{}: {}", display_pointer(&p.pointer), p.detail),
                            )
                        })
                        .collect(),
                )
            })?;
            Some((scene, document))
        }
        Some(_) => return Err(invalid("/reference", "must be an object of scene fields to change".into())),
    };
    let (reference, reference_document) = reference.unzip();
    Ok(Sweep { pointers, variants, reference, reference_document })
}

fn scene_problems(error: &crate::scene::SceneError) -> Vec<FieldError> {
    match error.field_errors() {
        [] => vec![FieldError::new("", error.to_string())],
        problems => problems.to_vec(),
    }
}

fn display_pointer(pointer: &str) -> &str {
    if pointer.is_empty() { "(scene)" } else { pointer }
}

/// Escapes a string for use as one JSON Pointer token.
fn escape(token: &str) -> String {
    token.replace('~', "~0").replace('/', "~1")
}

/// Sets the value at `pointer`: its parent must exist; an object gains a missing key, an array
/// index must be in range.
fn set(document: &mut Value, pointer: &str, value: Value) -> Result<(), String> {
    let Some((parent, last)) = pointer.rsplit_once('/') else {
        return Err("is not a JSON Pointer: it must start with `/`".into());
    };
    if !pointer.starts_with('/') {
        return Err("is not a JSON Pointer: it must start with `/`".into());
    }
    let key = last.replace("~1", "/").replace("~0", "~");
    match document.pointer_mut(parent) {
        Some(Value::Object(map)) => {
            map.insert(key, value);
            Ok(())
        }
        Some(Value::Array(items)) => match key.parse::<usize>() {
            Ok(i) if i < items.len() => {
                items[i] = value;
                Ok(())
            }
            _ => Err(format!("`{key}` is not an index of the {} items at `{parent}`", items.len())),
        },
        Some(_) => Err(format!("`{parent}` is not an object or array in the scene")),
        None => Err(format!("`{parent}` does not exist in the scene")),
    }
}

/// Applies a JSON merge patch (RFC 7386).
fn merge_patch(target: &mut Value, patch: Value) {
    match patch {
        Value::Object(patch) => {
            if !target.is_object() {
                *target = Value::Object(Map::new());
            }
            let map = target.as_object_mut().expect("made an object above");
            for (key, value) in patch {
                if value.is_null() {
                    map.remove(&key);
                } else {
                    merge_patch(map.entry(key).or_insert(Value::Null), value);
                }
            }
        }
        other => *target = other,
    }
}
