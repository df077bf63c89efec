//! One clock for every part of a run.
//!
//! Bench time is a [`Duration`] since the start of the run. Every task (device pollers, the
//! sequencer, the recorder, the simulators) reads it from the same [`Clock`]:
//!
//! - [`VirtualClock`] with [`run_virtual`]: a deterministic discrete-event executor. When every
//!   task is waiting, time jumps to the earliest deadline, so a simulated bench runs as fast as
//!   the CPU allows and gives the same result for the same seed. (tokio's paused clock does the
//!   same but measured ~3 µs per wake-up here, ten times this executor's cost.)
//! - [`SystemClock`]: tokio's clock, in real time or scaled (`--time-scale`), for real devices
//!   and simulators behind virtual ports.
//!
//! The orchestrator's code is the same under both: it only sleeps through the clock and spawns
//! through a [`futures::task::Spawn`].

use std::cmp::Reverse;
use std::collections::{BinaryHeap, HashMap};
use std::future::Future;
use std::pin::Pin;
use std::sync::{Arc, Mutex, MutexGuard};
use std::task::{Context, Poll, Waker};
use std::time::Duration;

use futures::future::BoxFuture;

/// Time since the start of the run.
pub type BenchTime = Duration;

/// The clock every task of a run shares.
pub trait Clock: Send + Sync + 'static {
    /// Bench time now.
    fn now(&self) -> BenchTime;
    /// A future that completes once `now() >= t` (immediately if already past).
    fn sleep_until(&self, t: BenchTime) -> BoxFuture<'static, ()>;
    /// True when time is simulated (jumps when all tasks wait), false for wall-clock time.
    fn is_virtual(&self) -> bool;
    /// A future that completes after `d` of bench time.
    fn sleep(&self, d: Duration) -> BoxFuture<'static, ()> {
        self.sleep_until(self.now() + d)
    }
}

/// Run `fut` with a limit of `limit` bench time; `None` if the limit passed first.
pub async fn timeout<F: Future>(clock: &dyn Clock, limit: Duration, fut: F) -> Option<F::Output> {
    let sleep = clock.sleep(limit);
    futures::pin_mut!(fut);
    match futures::future::select(fut, sleep).await {
        futures::future::Either::Left((v, _)) => Some(v),
        futures::future::Either::Right(((), _)) => None,
    }
}

#[derive(Default)]
struct VirtualState {
    now: Duration,
    next_id: u64,
    deadlines: BinaryHeap<Reverse<(Duration, u64)>>,
    wakers: HashMap<u64, Waker>,
}

/// Simulated time that advances only when [`run_virtual`] finds every task waiting.
#[derive(Clone, Default)]
pub struct VirtualClock {
    state: Arc<Mutex<VirtualState>>,
}

impl VirtualClock {
    /// A clock at bench time zero.
    pub fn new() -> Self {
        Self::default()
    }

    fn lock(&self) -> MutexGuard<'_, VirtualState> {
        // A poisoned lock only means a task panicked while holding it; the state is a plain
        // timer heap that stays consistent, so keep going.
        self.state.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Jump to the earliest pending deadline and wake every sleeper due then. Returns the new
    /// time, or `None` if nobody is sleeping.
    pub fn advance(&self) -> Option<Duration> {
        let mut st = self.lock();
        let Reverse((t, _)) = *st.deadlines.peek()?;
        st.now = st.now.max(t);
        let mut due = Vec::new();
        while let Some(&Reverse((t2, id))) = st.deadlines.peek() {
            if t2 > st.now {
                break;
            }
            st.deadlines.pop();
            if let Some(w) = st.wakers.remove(&id) {
                due.push(w);
            }
        }
        let now = st.now;
        drop(st);
        due.into_iter().for_each(Waker::wake);
        Some(now)
    }
}

struct VirtualSleep {
    clock: VirtualClock,
    deadline: Duration,
    id: Option<u64>,
}

impl Future for VirtualSleep {
    type Output = ();
    fn poll(mut self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<()> {
        let mut st = self.clock.lock();
        if st.now >= self.deadline {
            if let Some(id) = self.id {
                st.wakers.remove(&id);
            }
            return Poll::Ready(());
        }
        let id = match self.id {
            Some(id) => id,
            None => {
                st.next_id += 1;
                let id = st.next_id;
                let d = self.deadline;
                st.deadlines.push(Reverse((d, id)));
                id
            }
        };
        st.wakers.insert(id, cx.waker().clone());
        drop(st);
        self.id = Some(id);
        Poll::Pending
    }
}

impl Drop for VirtualSleep {
    fn drop(&mut self) {
        if let Some(id) = self.id {
            // The heap entry stays until its time comes; without a waker it wakes nobody.
            self.clock.lock().wakers.remove(&id);
        }
    }
}

impl Clock for VirtualClock {
    fn now(&self) -> BenchTime {
        self.lock().now
    }
    fn sleep_until(&self, t: BenchTime) -> BoxFuture<'static, ()> {
        Box::pin(VirtualSleep { clock: self.clone(), deadline: t, id: None })
    }
    fn is_virtual(&self) -> bool {
        true
    }
}

/// Error from [`run_virtual`]: every task waits on something other than the clock.
#[derive(Debug, thiserror::Error)]
#[error("virtual-time deadlock at bench time {at:?}: every task waits and no timer is pending")]
pub struct Deadlock {
    /// Bench time when it happened.
    pub at: Duration,
}

/// Drive `make(spawner)` to completion in virtual time on a deterministic single-threaded
/// executor. `make` receives a spawner for the run's other tasks (which must be `'static`);
/// the main future itself may borrow.
pub fn run_virtual<T, F>(
    clock: &VirtualClock,
    make: impl FnOnce(futures::executor::LocalSpawner) -> F,
) -> Result<T, Deadlock>
where
    F: Future<Output = T>,
{
    let mut pool = futures::executor::LocalPool::new();
    let main = make(pool.spawner());
    futures::pin_mut!(main);
    let woken = Arc::new(WakeFlag::default());
    let waker = Waker::from(woken.clone());
    let mut cx = Context::from_waker(&waker);
    woken.set();
    loop {
        if woken.take() {
            if let Poll::Ready(v) = main.as_mut().poll(&mut cx) {
                return Ok(v);
            }
        }
        pool.run_until_stalled();
        if woken.is_set() {
            continue;
        }
        if clock.advance().is_none() {
            return Err(Deadlock { at: clock.now() });
        }
    }
}

/// Wakes the main future of [`run_virtual`] by setting a flag.
#[derive(Default)]
struct WakeFlag(std::sync::atomic::AtomicBool);

impl WakeFlag {
    fn set(&self) {
        self.0.store(true, std::sync::atomic::Ordering::Release);
    }
    fn is_set(&self) -> bool {
        self.0.load(std::sync::atomic::Ordering::Acquire)
    }
    fn take(&self) -> bool {
        self.0.swap(false, std::sync::atomic::Ordering::AcqRel)
    }
}

impl std::task::Wake for WakeFlag {
    fn wake(self: Arc<Self>) {
        self.set();
    }
}

/// tokio's clock, optionally running `scale` times faster than the wall clock.
#[derive(Clone, Debug)]
pub struct SystemClock {
    start: tokio::time::Instant,
    scale: f64,
}

impl SystemClock {
    /// A clock starting now, running at `scale` × real time (1.0 for real devices).
    ///
    /// # Panics
    /// Never; a non-finite or non-positive `scale` is treated as 1.0.
    pub fn new(scale: f64) -> Self {
        let scale = if scale.is_finite() && scale > 0.0 { scale } else { 1.0 };
        Self { start: tokio::time::Instant::now(), scale }
    }

    /// The time scale.
    pub fn scale(&self) -> f64 {
        self.scale
    }
}

impl Clock for SystemClock {
    fn now(&self) -> BenchTime {
        self.start.elapsed().mul_f64(self.scale)
    }
    fn sleep_until(&self, t: BenchTime) -> BoxFuture<'static, ()> {
        let at = self.start + t.div_f64(self.scale);
        Box::pin(tokio::time::sleep_until(at))
    }
    fn is_virtual(&self) -> bool {
        false
    }
}

/// Spawns onto the current tokio runtime, so run code written against
/// [`futures::task::Spawn`] runs as tokio tasks.
#[derive(Clone, Copy, Debug, Default)]
pub struct TokioSpawner;

impl futures::task::Spawn for TokioSpawner {
    fn spawn_obj(
        &self,
        future: futures::task::FutureObj<'static, ()>,
    ) -> Result<(), futures::task::SpawnError> {
        tokio::spawn(future);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use futures::task::SpawnExt;

    #[test]
    fn virtual_time_interleaves_tasks_by_deadline() {
        let clock = VirtualClock::new();
        let log: Arc<Mutex<Vec<(u64, &'static str)>>> = Default::default();
        let c = clock.clone();
        let l = log.clone();
        let end = run_virtual(&clock, move |sp| async move {
            let (c1, l1) = (c.clone(), l.clone());
            let a = sp
                .spawn_with_handle(async move {
                    for i in 1..=3u64 {
                        c1.sleep_until(Duration::from_millis(100 * i)).await;
                        l1.lock().map(|mut v| v.push((c1.now().as_millis() as u64, "a"))).ok();
                    }
                })
                .ok();
            for i in 1..=2u64 {
                c.sleep_until(Duration::from_millis(150 * i)).await;
                l.lock().map(|mut v| v.push((c.now().as_millis() as u64, "b"))).ok();
            }
            if let Some(a) = a {
                a.await;
            }
            c.now()
        })
        .expect("no deadlock");
        assert_eq!(end, Duration::from_millis(300));
        let got = log.lock().map(|v| v.clone()).unwrap_or_default();
        // Sleepers due at the same instant wake in the order they went to sleep: b (at 150) before a (at 200).
        assert_eq!(got, vec![(100, "a"), (150, "b"), (200, "a"), (300, "b"), (300, "a")]);
    }

    #[test]
    fn virtual_deadlock_is_reported_not_hung() {
        let clock = VirtualClock::new();
        let r = run_virtual(&clock, |_| futures::future::pending::<()>());
        assert!(r.is_err());
    }

    #[test]
    fn virtual_timeout_fires_at_limit() {
        let clock = VirtualClock::new();
        let c = clock.clone();
        let r = run_virtual(&clock, move |_| async move {
            let r = timeout(&c, Duration::from_secs(2), c.sleep(Duration::from_secs(5))).await;
            (r, c.now())
        })
        .expect("runs");
        assert_eq!(r, (None, Duration::from_secs(2)));
    }

    #[tokio::test(start_paused = true)]
    async fn system_clock_scales_time() {
        let c = SystemClock::new(50.0);
        c.sleep_until(Duration::from_secs(100)).await;
        let now = c.now();
        assert!(now >= Duration::from_secs(100) && now < Duration::from_millis(100_100), "{now:?}");
    }
}
