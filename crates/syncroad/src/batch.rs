//! The one batch runner: the runs a command planned, `jobs` at a time on one rayon pool, with
//! progress on stderr and Ctrl-C (the interrupt flag) honoured between runs. `compare` (and
//! `regress` through it), `sweep` and `map` (through the sweep) all run their plans here.
//!
//! Each job is a closure that runs one planned run to its end and hands back what the command
//! keeps of it (a record, a table row) with the error the progress line names; the closure does
//! its own per-run work (writing the run's folder, streaming its row) as soon as the run ends,
//! so nothing finished waits for the rest of the batch.

use std::sync::atomic::{AtomicBool, Ordering};

use rayon::prelude::*;

use crate::progress::Progress;

/// How one job ended.
pub enum JobEnd<R> {
    /// It ran to its end (or failed): what the command keeps, and the failure for the log.
    Done(R, Option<String>),
    /// It was stopped by the interrupt flag before it finished.
    Interrupted,
}

/// Runs `work` on every item, at most `jobs` at once, labelled `label` in the progress report
/// (shown as `shown` says, see [`Progress::shown`]) and each item by `name`. Returns one entry per item in item order: `Some` for a job that
/// ended, `None` for one interrupted or never started because the interrupt flag was set.
///
/// # Errors
/// The thread pool could not be built.
pub fn run<T, R, N, W>(
    (label, shown): (&'static str, Option<crate::progress::ProgressMode>),
    jobs: usize,
    interrupt: &AtomicBool,
    items: &[T],
    name: N,
    work: W,
) -> anyhow::Result<Vec<Option<R>>>
where
    T: Sync,
    R: Send,
    N: Fn(&T) -> String + Sync,
    W: Fn(&T) -> JobEnd<R> + Sync,
{
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(jobs.min(items.len()).max(1))
        .build()?;
    let progress = Progress::shown(label, items.len() as u64, shown);
    let ends = pool.install(|| {
        items
            .par_iter()
            .map(|item| {
                if interrupt.load(Ordering::SeqCst) {
                    return None;
                }
                match work(item) {
                    JobEnd::Done(kept, error) => {
                        progress.finished(&name(item), error.as_deref());
                        Some(kept)
                    }
                    JobEnd::Interrupted => None,
                }
            })
            .collect()
    });
    progress.done();
    Ok(ends)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::AtomicUsize;

    #[test]
    fn results_keep_item_order_and_an_interrupt_stops_the_rest() {
        let flag = AtomicBool::new(false);
        let items: Vec<usize> = (0..20).collect();
        let out = run(
            ("test", None),
            3,
            &flag,
            &items,
            |i| i.to_string(),
            |&i| JobEnd::Done(i * i, (i % 7 == 0).then(|| "seven".into())),
        )
        .unwrap();
        assert_eq!(out, items.iter().map(|i| Some(i * i)).collect::<Vec<_>>());

        // One job at a time: the third sets the flag, so no later job starts.
        let started = AtomicUsize::new(0);
        let out = run(
            ("test", None),
            1,
            &flag,
            &items,
            |i| i.to_string(),
            |&i| {
                started.fetch_add(1, Ordering::SeqCst);
                if i == 2 {
                    flag.store(true, Ordering::SeqCst);
                    return JobEnd::Interrupted;
                }
                JobEnd::Done(i, None)
            },
        )
        .unwrap();
        assert_eq!(started.load(Ordering::SeqCst), 3);
        assert_eq!(&out[..3], &[Some(0), Some(1), None]);
        assert!(out[3..].iter().all(Option::is_none));
    }
}
