//! Effects ([`bench_physics::effects`]) in the TOML files read with serde (model file, bench
//! config): the range checks that serde cannot do, located at the offending value.

use bench_physics::effects::Effects;

/// The first parameter of `effects` that is not finite, or not positive where it must be,
/// as (1-based line, column, message), located in `text` under the table at `table_path`
/// (e.g. `["effects"]`); the table's own position, or 1:1, when the key cannot be found.
pub fn check_located(
    effects: &Effects,
    text: &str,
    table_path: &[&str],
) -> Result<(), (usize, usize, String)> {
    for id in effects.ids() {
        let Some(values) = effects.param_values(id) else { continue };
        for (p, v) in id.param_names().into_iter().zip(values) {
            let why = if !v.is_finite() {
                "must be a finite number"
            } else if id.param_must_be_positive(p) && v <= 0.0 {
                "must be greater than zero"
            } else {
                continue;
            };
            let mut path: Vec<&str> = table_path.to_vec();
            path.extend([id.key(), p]);
            let span = crate::toml_doc::value_span(text, &path)
                .or_else(|| crate::toml_doc::value_span(text, table_path));
            let (line, column) = span.map_or((1, 1), |s| crate::toml_doc::line_col(text, s.start));
            let table = table_path.join(".");
            return Err((line, column, format!("[{table}] {}.{p} = {v}: {why}", id.key())));
        }
    }
    Ok(())
}
