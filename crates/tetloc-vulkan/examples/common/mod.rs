//! What the examples share: their command lines of `--flag [value]` options.

/// Calls `on(flag, value)` for each flag of the command line; `value()` takes the flag's value
/// (an error where the command line ends).
pub fn each_flag(
    mut on: impl FnMut(&str, &mut dyn FnMut() -> Result<String, String>) -> Result<(), String>,
) -> Result<(), String> {
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        on(&flag, &mut || it.next().ok_or(format!("{flag} needs a value")))?;
    }
    Ok(())
}

/// A count, with `_` separators allowed (`1_000_000`).
pub fn num(s: String) -> Result<usize, String> {
    s.replace('_', "").parse::<usize>().map_err(|e| format!("{s}: {e}"))
}
