//! The bounded queue between the HTTP side and the worker threads.
//!
//! A slot is reserved before a job is stored, so a full queue is refused before any work and a
//! stored job always finds its place. Workers block on a condition variable (they are plain
//! threads, not runtime tasks). A queued job can be taken out again when it is cancelled, and
//! closing the queue hands back every job still waiting.

use std::collections::VecDeque;
use std::sync::{Condvar, Mutex, MutexGuard, PoisonError};

use super::JobId;

/// A bounded FIFO of `T`s, each with the id of its job.
pub(super) struct Queue<T> {
    state: Mutex<State<T>>,
    ready: Condvar,
    capacity: usize,
}

struct State<T> {
    waiting: VecDeque<(JobId, T)>,
    reserved: usize,
    closed: bool,
}

/// A place in the queue, held between admission and push; dropping it frees the place.
pub(super) struct Slot<'a, T> {
    queue: &'a Queue<T>,
    used: bool,
}

impl<T> Queue<T> {
    pub(super) fn new(capacity: usize) -> Self {
        Self {
            state: Mutex::new(State { waiting: VecDeque::new(), reserved: 0, closed: false }),
            ready: Condvar::new(),
            capacity,
        }
    }

    fn lock(&self) -> MutexGuard<'_, State<T>> {
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// A place for one more job, or `None` when the queue is full or closed.
    pub(super) fn reserve(&self) -> Option<Slot<'_, T>> {
        let mut state = self.lock();
        if state.closed || state.waiting.len() + state.reserved >= self.capacity {
            return None;
        }
        state.reserved += 1;
        Some(Slot { queue: self, used: false })
    }

    /// The next job, blocking until there is one; `None` once the queue is closed and empty.
    pub(super) fn pop(&self) -> Option<(JobId, T)> {
        let mut state = self.lock();
        loop {
            if let Some(item) = state.waiting.pop_front() {
                return Some(item);
            }
            if state.closed {
                return None;
            }
            state = self.ready.wait(state).unwrap_or_else(PoisonError::into_inner);
        }
    }

    /// Takes a waiting job out of the queue.
    pub(super) fn remove(&self, id: &JobId) -> Option<T> {
        let mut state = self.lock();
        let index = state.waiting.iter().position(|(queued, _)| queued == id)?;
        state.waiting.remove(index).map(|(_, item)| item)
    }

    /// Refuses new jobs, wakes every worker, and returns the jobs still waiting.
    pub(super) fn close(&self) -> Vec<(JobId, T)> {
        let mut state = self.lock();
        state.closed = true;
        self.ready.notify_all();
        state.waiting.drain(..).collect()
    }

    /// Jobs waiting.
    pub(super) fn len(&self) -> usize {
        self.lock().waiting.len()
    }
}

impl<T> Slot<'_, T> {
    /// Puts the job in its reserved place. Returns it back if the queue closed meanwhile.
    pub(super) fn push(mut self, id: JobId, item: T) -> Result<(), T> {
        let mut state = self.queue.lock();
        state.reserved -= 1;
        self.used = true;
        if state.closed {
            return Err(item);
        }
        state.waiting.push_back((id, item));
        self.queue.ready.notify_one();
        Ok(())
    }
}

impl<T> Drop for Slot<'_, T> {
    fn drop(&mut self) {
        if !self.used {
            self.queue.lock().reserved -= 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reservations_count_against_capacity_and_free_on_drop() {
        let queue = Queue::<u32>::new(2);
        let a = queue.reserve().unwrap();
        let b = queue.reserve().unwrap();
        assert!(queue.reserve().is_none());
        drop(b);
        a.push(JobId::new(), 1).unwrap();
        assert_eq!(queue.len(), 1);
        assert!(queue.reserve().is_some());
    }

    #[test]
    fn removed_and_closed_jobs_come_back_in_order() {
        let queue = Queue::new(4);
        let ids: Vec<JobId> = (0..3).map(|_| JobId::new()).collect();
        for (n, id) in ids.iter().enumerate() {
            queue.reserve().unwrap().push(id.clone(), n).unwrap();
        }
        assert_eq!(queue.remove(&ids[1]), Some(1));
        assert_eq!(queue.remove(&ids[1]), None);
        let left: Vec<usize> = queue.close().into_iter().map(|(_, n)| n).collect();
        assert_eq!(left, [0, 2]);
        assert!(queue.pop().is_none());
        assert!(queue.reserve().is_none());
    }
}
