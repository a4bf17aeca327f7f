//! Parts of a render (`--shard K/N`) and their exact merge.
//!
//! A part keeps what the whole needs, not only its mean: the additive
//! quantities of its samples per pixel (camera sums and counts, splatted
//! sums, gradient pair sums, Metropolis chain sums), its additive totals
//! (light paths, mutations) and what every part of one render shares (the
//! scene's content hash, the seed, the integrator and its settings, and
//! quantities every part computes identically, such as Metropolis'
//! normalisation). Sums are written as two f32 channels each (the value
//! rounded to f32, and the rest), so that a part read back holds its f64
//! sums to about 2⁻⁴⁸; merging adds them in f64, which differs from one
//! process's sums only in the order of the additions.

use std::collections::BTreeMap;
use std::fmt;
use std::path::{Path, PathBuf};
use std::str::FromStr;

/// The K-th of N parts of a render (K from 0, as Slurm's array indices).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Shard {
    /// Which part.
    pub index: u32,
    /// Of how many.
    pub count: u32,
}

impl Shard {
    /// The whole render, as its only part.
    pub const WHOLE: Shard = Shard { index: 0, count: 1 };

    /// This part's share of `0 .. n` items (sample indices, chains): the
    /// ranges of the parts are disjoint, cover it, and differ in length by
    /// at most one.
    #[must_use]
    pub fn share(&self, n: u64) -> std::ops::Range<u64> {
        let at = |k: u64| k * n / u64::from(self.count);
        at(u64::from(self.index))..at(u64::from(self.index) + 1)
    }
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

/// A `--shard` that is not K/N with K < N.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BadShard(pub String);

impl fmt::Display for BadShard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "'{}' is not a part K/N of a render: K and N are integers with 0 ≤ K < N",
            self.0
        )
    }
}

impl std::error::Error for BadShard {}

impl FromStr for Shard {
    type Err = BadShard;

    fn from_str(s: &str) -> Result<Shard, BadShard> {
        let bad = || BadShard(s.to_string());
        let (k, n) = s.split_once('/').ok_or_else(bad)?;
        let (index, count) = (
            k.trim().parse().map_err(|_| bad())?,
            n.trim().parse().map_err(|_| bad())?,
        );
        if index >= count {
            return Err(bad());
        }
        Ok(Shard { index, count })
    }
}

/// What one part of a render holds (or the merge of several).
#[derive(Clone, Debug, PartialEq)]
pub struct Partial {
    /// Film width.
    pub width: u32,
    /// Film height.
    pub height: u32,
    /// Additive per-pixel quantities, by name, row by row.
    pub planes: BTreeMap<String, Vec<f64>>,
    /// Additive totals, by name.
    pub totals: BTreeMap<String, f64>,
    /// What every part of the render shares, by name.
    pub same: BTreeMap<String, String>,
}

impl Partial {
    /// An empty part of a `width` × `height` render.
    #[must_use]
    pub fn new(width: u32, height: u32) -> Partial {
        Partial {
            width,
            height,
            planes: BTreeMap::new(),
            totals: BTreeMap::new(),
            same: BTreeMap::new(),
        }
    }

    /// Adds three planes `name.R`, `name.G`, `name.B` from RGB sums.
    pub fn put_rgb(&mut self, name: &str, rgb: &[[f64; 3]]) {
        for (k, c) in ["R", "G", "B"].iter().enumerate() {
            let plane = rgb.iter().map(|v| v[k]).collect();
            self.planes.insert(format!("{name}.{c}"), plane);
        }
    }

    /// The RGB planes `name.R`, `name.G`, `name.B`, if all are there.
    #[must_use]
    pub fn rgb(&self, name: &str) -> Option<Vec<[f64; 3]>> {
        let [r, g, b] = ["R", "G", "B"].map(|c| self.planes.get(&format!("{name}.{c}")));
        let (r, g, b) = (r?, g?, b?);
        Some((0..r.len()).map(|i| [r[i], g[i], b[i]]).collect())
    }

    /// The plane `name`.
    #[must_use]
    pub fn plane(&self, name: &str) -> Option<&[f64]> {
        self.planes.get(name).map(Vec::as_slice)
    }

    /// The total `name` (0 if absent).
    #[must_use]
    pub fn total(&self, name: &str) -> f64 {
        self.totals.get(name).copied().unwrap_or(0.0)
    }

    /// Adds `other`'s planes and totals to these; the planes must match in
    /// names and sizes (see [`merge`], which checks it with the files named).
    fn add(&mut self, other: &Partial) {
        for (name, plane) in &mut self.planes {
            if let Some(o) = other.planes.get(name) {
                for (a, b) in plane.iter_mut().zip(o) {
                    *a += b;
                }
            }
        }
        for (name, total) in &mut self.totals {
            *total += other.total(name);
        }
    }
}

/// Why parts cannot be merged, each naming the file and the field.
#[derive(Debug)]
pub enum MergeError {
    /// A file that cannot be read as a part.
    Unreadable(PathBuf, String),
    /// Parts of different renders.
    Differs {
        /// The part that differs from the first.
        file: PathBuf,
        /// The first part.
        first: PathBuf,
        /// The field.
        field: String,
        /// Its value in the first part.
        expected: String,
        /// Its value in this one.
        found: String,
    },
    /// The same part given twice.
    Twice(PathBuf, PathBuf, Shard),
    /// Parts missing (unless a partial merge is asked for).
    Missing(Vec<u32>, u32),
    /// No part at all.
    Nothing,
}

impl fmt::Display for MergeError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            MergeError::Unreadable(p, why) => {
                write!(f, "{}: not a part of a render: {why}", p.display())
            }
            MergeError::Differs {
                file,
                first,
                field,
                expected,
                found,
            } => write!(
                f,
                "{}: its {field} is {found}, but {} has {expected}: parts of different renders are not merged",
                file.display(),
                first.display()
            ),
            MergeError::Twice(a, b, s) => write!(
                f,
                "{} and {} are the same part {s}: a part given twice would count its samples twice",
                a.display(),
                b.display()
            ),
            MergeError::Missing(ks, n) => write!(
                f,
                "parts {} of {n} are missing (--partial merges the parts given)",
                ks.iter().map(u32::to_string).collect::<Vec<_>>().join(", ")
            ),
            MergeError::Nothing => write!(f, "no part to merge"),
        }
    }
}

impl std::error::Error for MergeError {}

/// A merge: the sum of the parts, and the fraction of all parts it holds.
#[derive(Debug)]
pub struct Merged {
    /// The parts' sums.
    pub partial: Partial,
    /// Parts held over parts of the render (1 unless `--partial`).
    pub fraction: f64,
}

/// Merges `parts` (file and part), checking that they are parts of one
/// render, none twice and, unless `partial`, none missing.
///
/// # Errors
/// As [`MergeError`].
pub fn merge(parts: &[(PathBuf, Shard, Partial)], partial: bool) -> Result<Merged, MergeError> {
    let mut merger: Option<Merger> = None;
    for (file, shard, p) in parts {
        match &mut merger {
            None => merger = Some(Merger::new(file.clone(), *shard, p.clone())),
            Some(m) => m.add(file, *shard, p)?,
        }
    }
    merger.ok_or(MergeError::Nothing)?.finish(partial)
}

/// A merge under way: the parts are added one at a time, so that merging
/// many parts of a large film holds two of them in memory, not all.
#[derive(Debug)]
pub struct Merger {
    first_file: PathBuf,
    first_shard: Shard,
    sum: Partial,
    seen: BTreeMap<u32, PathBuf>,
}

impl Merger {
    /// A merge that starts from the part `shard` in `file`.
    #[must_use]
    pub fn new(file: PathBuf, shard: Shard, partial: Partial) -> Merger {
        let seen = BTreeMap::from([(shard.index, file.clone())]);
        Merger {
            first_file: file,
            first_shard: shard,
            sum: partial,
            seen,
        }
    }

    /// Adds the part `shard` in `file`.
    ///
    /// # Errors
    /// If it belongs to another render than the first part, or was added
    /// already.
    pub fn add(&mut self, file: &Path, shard: Shard, p: &Partial) -> Result<(), MergeError> {
        let first = &self.sum;
        let differs = |field: &str, expected: String, found: String| MergeError::Differs {
            file: file.to_path_buf(),
            first: self.first_file.clone(),
            field: field.to_string(),
            expected,
            found,
        };
        if shard.count != self.first_shard.count {
            let (a, b) = (self.first_shard.count, shard.count);
            return Err(differs("number of parts", a.to_string(), b.to_string()));
        }
        if (p.width, p.height) != (first.width, first.height) {
            let size = |p: &Partial| format!("{}×{}", p.width, p.height);
            return Err(differs("film size", size(first), size(p)));
        }
        for key in first.same.keys().chain(p.same.keys()) {
            let (a, b) = (first.same.get(key), p.same.get(key));
            if a != b {
                let show = |v: Option<&String>| v.cloned().unwrap_or_else(|| "nothing".into());
                return Err(differs(key, show(a), show(b)));
            }
        }
        let names = |p: &Partial| p.planes.keys().cloned().collect::<Vec<_>>().join(" ");
        if names(p) != names(first) {
            return Err(differs("channels", names(first), names(p)));
        }
        if let Some(other) = self.seen.get(&shard.index) {
            return Err(MergeError::Twice(other.clone(), file.to_path_buf(), shard));
        }
        self.seen.insert(shard.index, file.to_path_buf());
        self.sum.add(p);
        Ok(())
    }

    /// The merge of the parts added.
    ///
    /// # Errors
    /// If parts are missing and `partial` is false.
    pub fn finish(self, partial: bool) -> Result<Merged, MergeError> {
        let n = self.first_shard.count;
        let missing: Vec<u32> = (0..n).filter(|k| !self.seen.contains_key(k)).collect();
        if !missing.is_empty() && !partial {
            return Err(MergeError::Missing(missing, n));
        }
        Ok(Merged {
            fraction: self.seen.len() as f64 / f64::from(n),
            partial: self.sum,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shares_are_disjoint_and_cover_the_whole() {
        for n in [1u32, 2, 3, 7] {
            let mut next = 0;
            for k in 0..n {
                let r = Shard { index: k, count: n }.share(16);
                assert_eq!(r.start, next);
                next = r.end;
            }
            assert_eq!(next, 16);
        }
        assert_eq!("2/7".parse(), Ok(Shard { index: 2, count: 7 }));
        for bad in ["7/7", "1/0", "0/0", "a/2", "3", "-1/2"] {
            assert!(bad.parse::<Shard>().is_err(), "{bad}");
        }
    }
}
