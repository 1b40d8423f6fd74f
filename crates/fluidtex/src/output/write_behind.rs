//! Write-behind: a frame's files are written on a second thread while the
//! frame loop computes the next frame.
//!
//! Writing (PNG/EXR encoding, OBJ and glb, the debug views) is a third of a
//! frame at large atlases, and the method's stages cannot start the next
//! frame's work while the loop waits on it. [`scope`] runs the loop's body
//! on the calling thread and a worker on a scoped thread, joined by a
//! rendezvous channel: handing frame t+1 to the worker waits until it has
//! finished frame t, so at most one frame is being written while one is
//! computed (memory stays that of two frames, whatever the sequence
//! length). The worker takes jobs in the order they are handed over and
//! stops at its first error, so nothing of a later frame is written after
//! a frame that failed (the saved state never runs ahead of the files).
//! Results come back in order. Without write-behind ([`Mode::Inline`]) the
//! same jobs run in place, in the same order: the files are the same
//! either way, only the wall clock differs.
//!
//! A scoped thread and two `std::sync::mpsc` channels are the whole
//! mechanism; a thread-pool crate would add nothing here: the worker's own
//! parallel work (encoders, the OBJ formatter) already runs on rayon's
//! pool, which both threads share.

use std::sync::mpsc::{Receiver, SyncSender};

/// Whether jobs run on the worker thread or in place.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// On a second thread, overlapping the caller's next frame.
    Behind,
    /// In place, when handed over.
    Inline,
}

/// The caller's end: hands jobs over and collects their results.
pub struct Worker<'w, J, R, E> {
    inner: Inner<'w, J, R, E>,
}

enum Inline<'w, J, R, E> {
    Running(&'w mut (dyn FnMut(J) -> Result<R, E> + 'w)),
    /// The work failed once: later jobs are dropped, as on the thread.
    Stopped,
}

enum Inner<'w, J, R, E> {
    Behind {
        jobs: Option<SyncSender<J>>,
        results: Receiver<Result<R, E>>,
    },
    Inline {
        work: Inline<'w, J, R, E>,
        results: Vec<Result<R, E>>,
    },
}

impl<J, R, E> Worker<'_, J, R, E> {
    /// Hands `job` over. Behind: waits until the worker has taken it (it is
    /// then done with every earlier job). A job handed over after the work
    /// failed is dropped; the failure comes back from [`Worker::ready`] or
    /// [`Worker::finish`].
    pub fn submit(&mut self, job: J) {
        match &mut self.inner {
            Inner::Behind { jobs, .. } => {
                if let Some(jobs) = jobs {
                    // An error means the worker stopped after a failure,
                    // which its result channel reports.
                    let _ = jobs.send(job);
                }
            }
            Inner::Inline { work, results } => {
                if let Inline::Running(f) = work {
                    let r = f(job);
                    if r.is_err() {
                        *work = Inline::Stopped;
                    }
                    results.push(r);
                }
            }
        }
    }

    /// The results that are in, oldest first, without waiting.
    pub fn ready(&mut self) -> Vec<Result<R, E>> {
        match &mut self.inner {
            Inner::Behind { results, .. } => results.try_iter().collect(),
            Inner::Inline { results, .. } => std::mem::take(results),
        }
    }

    /// Waits for every job handed over to finish; their results, oldest
    /// first.
    pub fn finish(&mut self) -> Vec<Result<R, E>> {
        match &mut self.inner {
            Inner::Behind { jobs, results } => {
                // Closing the job channel ends the worker's loop.
                jobs.take();
                results.iter().collect()
            }
            Inner::Inline { results, .. } => std::mem::take(results),
        }
    }
}

/// Runs `body` with a [`Worker`] that applies `work` to each job handed
/// over: on a scoped thread ([`Mode::Behind`]) or in place. Every job handed
/// over has finished when this returns, `body`'s early returns included.
pub fn scope<J, R, E, T>(
    mode: Mode,
    mut work: impl FnMut(J) -> Result<R, E> + Send,
    body: impl FnOnce(&mut Worker<'_, J, R, E>) -> T,
) -> T
where
    J: Send,
    R: Send,
    E: Send,
{
    match mode {
        Mode::Inline => body(&mut Worker {
            inner: Inner::Inline {
                work: Inline::Running(&mut work),
                results: Vec::new(),
            },
        }),
        Mode::Behind => std::thread::scope(|s| {
            // Capacity 0: a hand-over meets the worker's receive, so one
            // job is in the worker's hands at a time.
            let (jobs, jobs_in) = std::sync::mpsc::sync_channel::<J>(0);
            let (results_out, results) = std::sync::mpsc::channel();
            s.spawn(move || {
                for job in jobs_in {
                    let r = work(job);
                    let failed = r.is_err();
                    if results_out.send(r).is_err() || failed {
                        break;
                    }
                }
            });
            let mut worker = Worker {
                inner: Inner::Behind {
                    jobs: Some(jobs),
                    results,
                },
            };
            let out = body(&mut worker);
            // Lets the worker's loop end; the scope joins it.
            drop(worker);
            out
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicUsize, Ordering};
    use std::sync::{Arc, Mutex};

    /// Hands jobs `0..n` over as a frame loop does (collecting what is
    /// ready after each), then every result still due.
    fn submit_all<R, E>(w: &mut Worker<'_, u32, R, E>, n: u32) -> Vec<Result<R, E>> {
        let mut got = Vec::new();
        for j in 0..n {
            w.submit(j);
            got.extend(w.ready());
        }
        got.extend(w.finish());
        got
    }

    /// Results come back in submission order, all of them, in both modes,
    /// and are the same in both.
    #[test]
    fn results_come_back_in_order_in_both_modes() {
        let run = |mode| {
            scope(
                mode,
                |j: u32| Ok::<u32, String>(j * j),
                |w| submit_all(w, 50),
            )
        };
        let expected: Vec<Result<u32, String>> = (0..50).map(|j| Ok(j * j)).collect();
        assert_eq!(run(Mode::Behind), expected);
        assert_eq!(run(Mode::Inline), expected);
    }

    /// After a failure no later job runs (nothing of a later frame is
    /// written), and the failure is the last result.
    #[test]
    fn nothing_runs_after_a_failure() {
        for mode in [Mode::Behind, Mode::Inline] {
            let ran = Arc::new(Mutex::new(Vec::new()));
            let log = Arc::clone(&ran);
            let results = scope(
                mode,
                move |j: u32| {
                    log.lock().unwrap().push(j);
                    if j == 3 {
                        Err(format!("job {j}"))
                    } else {
                        Ok(j)
                    }
                },
                |w| submit_all(w, 8),
            );
            assert_eq!(*ran.lock().unwrap(), vec![0, 1, 2, 3], "{mode:?}");
            assert_eq!(
                results,
                vec![Ok(0), Ok(1), Ok(2), Err("job 3".to_string())],
                "{mode:?}"
            );
        }
    }

    /// A job that takes `ms` milliseconds, then counts itself in `finished`.
    fn slow_counted_job(
        ms: u64,
        finished: &Arc<AtomicUsize>,
    ) -> impl FnMut(u32) -> Result<(), ()> + Send + use<> {
        let counter = Arc::clone(finished);
        move |_| {
            std::thread::sleep(std::time::Duration::from_millis(ms));
            counter.fetch_add(1, Ordering::SeqCst);
            Ok(())
        }
    }

    /// Behind, at most one job is in the worker's hands while the caller
    /// goes on: when a hand-over returns, every job before the one just
    /// handed over has finished.
    #[test]
    fn a_hand_over_waits_for_the_job_before() {
        let finished = Arc::new(AtomicUsize::new(0));
        scope(Mode::Behind, slow_counted_job(5, &finished), |w| {
            for j in 0..6 {
                w.submit(j);
                let done = finished.load(Ordering::SeqCst);
                assert!(done >= j as usize, "job {j}: only {done} finished");
            }
            w.finish();
            assert_eq!(finished.load(Ordering::SeqCst), 6);
        });
    }

    /// An early return from the body (an error of the frame loop) still
    /// lets the job in the worker's hands finish before `scope` returns.
    #[test]
    fn an_early_return_lets_the_last_job_finish() {
        let finished = Arc::new(AtomicUsize::new(0));
        let out: Result<(), &str> = scope(Mode::Behind, slow_counted_job(20, &finished), |w| {
            w.submit(0);
            w.submit(1);
            Err("the loop failed")
        });
        assert_eq!(out, Err("the loop failed"));
        assert_eq!(finished.load(Ordering::SeqCst), 2);
    }
}
