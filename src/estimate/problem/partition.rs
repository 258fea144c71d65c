//! The batches of the batch means and of the jackknife: runs of whole blocks of one
//! experiment, about `N/B` samples each ([`super::batches`], [`crate::estimate::jackknife`]).

/// One batch: the blocks `blocks` of experiment `experiment`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct Batch {
    /// The experiment's index.
    pub experiment: usize,
    /// Its blocks' indices within the experiment.
    pub blocks: std::ops::Range<usize>,
    /// The experiment's short tail that joined it (summed apart, then added), or empty.
    pub tail: std::ops::Range<usize>,
}

impl Batch {
    /// The batch's sum of `values` (one per block of its experiment), its blocks summed in
    /// order, then its tail's.
    pub(crate) fn sum<T>(&self, values: &[T], zero: impl Fn() -> T) -> T
    where
        T: for<'a> std::ops::AddAssign<&'a T>,
    {
        let mut s = zero();
        for v in &values[self.blocks.clone()] {
            s += v;
        }
        if !self.tail.is_empty() {
            let mut t = zero();
            for v in &values[self.tail.clone()] {
                t += v;
            }
            s += &t;
        }
        s
    }
}

/// The batches of about `total/target` samples each (`total` the samples of all
/// experiments, whose blocks counted `counts`): runs of whole blocks of one experiment, cut
/// at the block boundary nearest the length aimed at; a short tail (under half a batch)
/// joins the batch before it in the same experiment.
pub(crate) fn partition<'c>(
    counts: impl Iterator<Item = &'c [usize]>,
    total: usize,
    target: usize,
) -> Vec<Batch> {
    let length = total.div_ceil(target.max(1));
    let mut batches: Vec<Batch> = Vec::new();
    for (e, counts) in counts.enumerate() {
        let first = batches.len();
        let (mut n, mut start) = (0, 0);
        for (b, &c) in counts.iter().enumerate() {
            n += c;
            if n + c / 2 >= length {
                batches.push(Batch { experiment: e, blocks: start..b + 1, tail: 0..0 });
                (n, start) = (0, b + 1);
            }
        }
        if n > 0 {
            let joins = batches.len() > first && 2 * n < length;
            match batches.last_mut().filter(|_| joins) {
                Some(last) => last.tail = start..counts.len(),
                None => batches.push(Batch { experiment: e, blocks: start..counts.len(), tail: 0..0 }),
            }
        }
    }
    batches
}
