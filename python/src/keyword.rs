//! One Python keyword's value converted to a typed value, a wrong one refused naming the
//! keyword and quoting the value (`voltage='referense': expected actual or reference`).

use crate::errors::OptionError;
use greybox::app::Choice;
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyString};

/// An `OptionError` for keyword `key` given `value` (its `repr`): `reason`, without the
/// value the reason may quote first.
fn bad(key: &str, value: &Bound<'_, PyAny>, reason: &str) -> PyErr {
    let shown = value.repr().map(|r| r.to_string()).unwrap_or_else(|_| "?".into());
    let reason = reason.split_once("`: ").filter(|(v, _)| v.starts_with('`')).map_or(reason, |(_, r)| r);
    OptionError::new_err(format!("{key}={shown}: {reason}"))
}

/// Each keyword of `options` with its value to `take`, in the order given; those given as
/// `None` left out (at their defaults).
///
/// Errors: a key that is not a string, and those of `take`.
pub fn each(
    options: &Bound<'_, PyDict>,
    mut take: impl FnMut(&Value<'_, '_>) -> PyResult<()>,
) -> PyResult<()> {
    for (k, v) in options.iter() {
        let key: String = k.extract()?;
        if !v.is_none() {
            take(&Value { key: &key, v: &v })?;
        }
    }
    Ok(())
}

/// One keyword's value as a typed value.
pub struct Value<'a, 'py> {
    /// The keyword.
    pub key: &'a str,
    /// Its value.
    pub v: &'a Bound<'py, PyAny>,
}

impl<'py> Value<'_, 'py> {
    /// The `OptionError` of this keyword's value for `reason`.
    pub fn err(&self, reason: &str) -> PyErr {
        bad(self.key, self.v, reason)
    }

    /// A word: a string, or a number written as Python writes it (`repr`, the shortest
    /// exact form of a float), for the values that are a word or a number (`delay=2`).
    pub fn word(&self) -> PyResult<String> {
        if self.v.is_instance_of::<PyBool>() {
            return Err(self.err("expected a string or a number, not a bool"));
        }
        if self.v.is_instance_of::<PyString>() {
            return self.v.extract();
        }
        if self.v.is_instance_of::<PyInt>() || self.v.is_instance_of::<PyFloat>() {
            return Ok(self.v.repr()?.to_string());
        }
        Err(self.err("expected a string or a number"))
    }

    /// The value parsed from its word by `parse`.
    pub fn parsed<T>(&self, parse: impl Fn(&str) -> Result<T, String>) -> PyResult<T> {
        parse(&self.word()?).map_err(|e| self.err(&e))
    }

    /// One of `T`'s names.
    pub fn choice<T: Choice>(&self) -> PyResult<T> {
        if !self.v.is_instance_of::<PyString>() {
            return Err(self.err(&format!("expected one of {}", T::LISTED.join(", "))));
        }
        self.parsed(T::parse_choice)
    }

    /// A string.
    pub fn text(&self) -> PyResult<String> {
        if !self.v.is_instance_of::<PyString>() {
            return Err(self.err("expected a string"));
        }
        self.v.extract()
    }

    /// A finite number: an int, a float, or a string of one (the command line's word).
    pub fn number(&self) -> PyResult<f64> {
        let x: f64 = if self.v.is_instance_of::<PyString>() {
            self.text()?.trim().parse().map_err(|_| self.err("expected a number"))?
        } else if self.v.is_instance_of::<PyBool>()
            || !(self.v.is_instance_of::<PyInt>() || self.v.is_instance_of::<PyFloat>())
        {
            return Err(self.err("expected a number"));
        } else {
            self.v.extract()?
        };
        if !x.is_finite() {
            return Err(self.err("expected a finite number"));
        }
        Ok(x)
    }

    /// A number, or `None`.
    pub fn optional_number(&self) -> PyResult<Option<f64>> {
        if self.v.is_none() { Ok(None) } else { self.number().map(Some) }
    }

    /// A whole number ≥ 0 that fits `T`: an int, or a string of one.
    pub fn count<T: TryFrom<u64>>(&self) -> PyResult<T> {
        let n: u64 = if self.v.is_instance_of::<PyString>() {
            self.text()?.trim().parse().map_err(|_| self.err("expected a whole number ≥ 0"))?
        } else if self.v.is_instance_of::<PyBool>() || !self.v.is_instance_of::<PyInt>() {
            return Err(self.err("expected a whole number"));
        } else {
            self.v.extract().map_err(|_| self.err("expected a whole number ≥ 0"))?
        };
        T::try_from(n).map_err(|_| self.err("out of range"))
    }

    /// `True` or `False`.
    pub fn flag(&self) -> PyResult<bool> {
        if !self.v.is_instance_of::<PyBool>() {
            return Err(self.err("expected True or False"));
        }
        self.v.extract()
    }

    /// A list of items, or one item; a string is the command line's comma-separated list
    /// (`"r_s,k_e"`), not its characters.
    pub fn items(&self) -> PyResult<Vec<Bound<'py, PyAny>>> {
        let py = self.v.py();
        if self.v.is_instance_of::<PyString>() {
            let text: String = self.v.extract()?;
            return Ok(text.split(',').map(|w| PyString::new(py, w.trim()).into_any()).collect());
        }
        if !self.v.hasattr("__iter__")? {
            return Ok(vec![self.v.clone()]);
        }
        self.v.try_iter()?.collect()
    }

    /// [`Value::items`] as numbers.
    pub fn numbers(&self) -> PyResult<Vec<f64>> {
        self.items()?.iter().map(|x| Value { key: self.key, v: x }.number()).collect()
    }

    /// [`Value::items`] as strings.
    pub fn texts(&self) -> PyResult<Vec<String>> {
        self.items()?.iter().map(|x| Value { key: self.key, v: x }.text()).collect()
    }

    /// Three names: a list of three or `"a,b,c"`.
    pub fn three(&self) -> PyResult<[String; 3]> {
        let names: Vec<String> = if self.v.is_instance_of::<PyString>() {
            self.text()?.split(',').map(|n| n.trim().to_string()).collect()
        } else {
            self.texts()?
        };
        match <[String; 3]>::try_from(names) {
            Ok(n) if n.iter().all(|x| !x.is_empty()) => Ok(n),
            _ => Err(self.err("expected three column names, e.g. [\"ia\", \"ib\", \"ic\"]")),
        }
    }

    /// A mapping `{name: value}` (or a list of the command line's words) as words
    /// `NAME=VALUE`, `NAME` for `None`, `NAME:LO:HI` for a pair.
    pub fn pairs(&self) -> PyResult<Vec<String>> {
        let Ok(map) = self.v.cast::<PyDict>() else { return self.texts() };
        let mut out = Vec::new();
        for (k, v) in map.iter() {
            let name: String = Value { key: self.key, v: &k }.text()?;
            let item = Value { key: self.key, v: &v };
            if v.is_none() {
                out.push(name);
            } else if v.is_instance_of::<PyString>()
                || v.is_instance_of::<PyInt>()
                || v.is_instance_of::<PyFloat>()
            {
                out.push(format!("{name}={}", item.word()?));
            } else {
                let xs = item.numbers()?;
                let xs: Vec<String> = xs.iter().map(|x| format!("{x:?}")).collect();
                out.push(format!("{name}:{}", xs.join(":")));
            }
        }
        Ok(out)
    }
}
