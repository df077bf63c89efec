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

/// Hashes a sleeper's id (a counter) by one multiplication: the ids are unique and nobody
/// chooses them, so the default hasher's protection against chosen keys buys nothing, and its
/// cost was a tenth of a simulated run's executor thread (two map operations per sleep).
#[derive(Default)]
struct IdHasher(u64);

impl std::hash::Hasher for IdHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0 << 8 | u64::from(b)).wrapping_mul(0x9E37_79B9_7F4A_7C15);
        }
    }
    fn write_u64(&mut self, id: u64) {
        // Fibonacci hashing: consecutive ids spread over the high bits the table probes with.
        self.0 = id.wrapping_mul(0x9E37_79B9_7F4A_7C15);
    }
}

#[derive(Default)]
struct VirtualState {
    now: Duration,
    next_id: u64,
    deadlines: BinaryHeap<Reverse<(Duration, u64)>>,
    wakers: HashMap<u64, Waker, std::hash::BuildHasherDefault<IdHasher>>,
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

/// Real time × `scale` like [`SystemClock`], but held at bench time zero until
/// [`HeldClock::start`] is called: for a replay served to programs that connect later, whose
/// bench time should begin with their first request rather than when the server started.
#[derive(Clone, Debug)]
pub struct HeldClock {
    start: Arc<tokio::sync::watch::Sender<Option<tokio::time::Instant>>>,
    scale: f64,
}

impl HeldClock {
    /// A held clock that will run at `scale` × real time (non-finite or non-positive: 1.0).
    pub fn new(scale: f64) -> Self {
        let scale = if scale.is_finite() && scale > 0.0 { scale } else { 1.0 };
        Self { start: Arc::new(tokio::sync::watch::Sender::new(None)), scale }
    }

    /// Start the clock now; later calls do nothing. True for the call that started it.
    pub fn start(&self) -> bool {
        self.start.send_if_modified(|start| {
            let first = start.is_none();
            start.get_or_insert_with(tokio::time::Instant::now);
            first
        })
    }

    /// Whether [`HeldClock::start`] was called.
    pub fn is_started(&self) -> bool {
        self.start.borrow().is_some()
    }
}

impl Clock for HeldClock {
    fn now(&self) -> BenchTime {
        self.start.borrow().map_or(Duration::ZERO, |s| s.elapsed().mul_f64(self.scale))
    }
    fn sleep_until(&self, t: BenchTime) -> BoxFuture<'static, ()> {
        if t.is_zero() {
            return Box::pin(std::future::ready(()));
        }
        let mut started = self.start.subscribe();
        let scale = self.scale;
        Box::pin(async move {
            // Err: every handle of the clock is gone, so nothing can start it: never wake.
            let start = match started.wait_for(Option::is_some).await {
                Ok(start) => *start,
                Err(_) => None,
            };
            match start {
                Some(start) => tokio::time::sleep_until(start + t.div_f64(scale)).await,
                None => std::future::pending().await,
            }
        })
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

    #[tokio::test(start_paused = true)]
    async fn held_clock_stays_at_zero_until_started_then_runs_scaled() {
        let clock = HeldClock::new(10.0);
        let c = clock.clone();
        let sleeper = tokio::spawn(async move {
            c.sleep_until(Duration::from_secs(5)).await;
            tokio::time::Instant::now()
        });
        tokio::time::sleep(Duration::from_secs(100)).await;
        assert_eq!(clock.now(), Duration::ZERO);
        assert!(!clock.is_started() && !sleeper.is_finished());
        // A zero deadline is already reached.
        clock.sleep_until(Duration::ZERO).await;

        let t0 = tokio::time::Instant::now();
        assert!(clock.start());
        assert!(!clock.start(), "only the first call starts it");
        let woke = sleeper.await.expect("sleeper");
        assert_eq!(woke - t0, Duration::from_millis(500), "5 s of bench time at 10× real time");
        assert_eq!(clock.now(), Duration::from_secs(5));
        // A deadline already past completes at once.
        clock.sleep_until(Duration::from_secs(1)).await;
        assert_eq!(tokio::time::Instant::now(), woke);
    }

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
