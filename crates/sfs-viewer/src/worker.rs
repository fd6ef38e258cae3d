//! The viewer's background solver thread: a named thread that owns solver
//! runs, takes commands and reports typed [`Event`]s over bounded
//! crossbeam channels, and calls a waker (the app passes
//! `ctx.request_repaint()`) after every event it sends, so it needs no egui.
//!
//! Protocol:
//! - [`Worker::submit`] hands out increasing [`JobId`]s. A newer job
//!   supersedes every older one: a running solve stops at its next SOR sweep,
//!   and of the jobs queued while the worker was busy only the newest starts;
//!   the older ones get [`Event::Cancelled`] without [`Event::Started`].
//! - A job that starts sends `Started`, then `Progress` and `Level` events,
//!   then exactly one of `Finished`, `Failed` or `Cancelled`. A solver error
//!   or panic becomes `Failed` and the worker serves the next job.
//! - `Progress` is dropped when the event channel is full. Other events wait
//!   for room, except that an event of a job that is already stale
//!   (superseded or cancelled) is dropped when the channel is full: the UI
//!   discards stale events anyway, and waiting for it could deadlock a UI
//!   that is itself waiting in [`Worker::submit`].
//! - Dropping the [`Worker`] requests shutdown, cancels the running solve and
//!   joins the thread. If the UI side is gone the thread ends.
//! - A job whose depth unit is to be decided (known depths, an object
//!   distance, or lights off the centre with no scale given) runs the
//!   core's one decision, [`depth_unit::solve_photograph`] (linearised
//!   scheme), instead of the [`SolveFn`]: every solve of its scale search
//!   streams its levels (level indices start again at 0 with each solve),
//!   and where the search rescaled the last solve's depth a last `Level`
//!   event carries the rescaled depth; `Finished` then holds the
//!   [`DepthUnit`] (and with it the known distances' fit).
//! - With `reflectance auto` the core compares the materials once per job
//!   (`material_fit`; no events while it runs, only cancellation): a scale
//!   estimate or known-depth search runs as Lambert, what `auto` stands
//!   for, and the fit follows at the scale found. It reaches the UI in the
//!   finished [`Solution::material_fit`].
//! - A photometric-stereo set ([`Worker::submit_set`], a [`SetRequest`]) is
//!   a job like any other (ids, superseding, cancellation, levels): it runs
//!   the [`SetSolveFn`] ([`solve_photometric`] by default) and ends with
//!   [`Event::SetFinished`] instead of `Finished`.

use std::any::Any;
use std::fmt;
use std::io;
use std::panic::{self, AssertUnwindSafe};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::thread::{self, JoinHandle};
use std::time::{Duration, Instant};

use crossbeam_channel::{
    Receiver, RecvTimeoutError, SendTimeoutError, Sender, TryRecvError, TrySendError, bounded,
};

use sfs_core::params::{InitialDepth, SolverParams};
use sfs_core::photograph_solve::{PhotographSolve, PhotographSolveError, SolvedPhotograph};
use sfs_core::solver::photometric::{
    PhotometricParams, PhotometricProblem, PhotometricSolution, solve_photometric,
};
use sfs_core::solver::pyramid;
use sfs_core::solver::{
    IterationReport, LevelResult, Problem, Solution, SolveError, SolveObserver,
};

/// Commands queued while the worker is busy (submits beyond this wait).
const COMMAND_CAPACITY: usize = 64;
/// Events not yet drained by the UI.
const EVENT_CAPACITY: usize = 256;
/// How often a blocked event send re-checks shutdown and staleness.
const SEND_POLL: Duration = Duration::from_millis(20);
/// The error of a job whose thread has gone.
const THREAD_STOPPED: &str = "the solver thread has stopped";

/// Identifies one submitted solve; ids increase with every submit, from 1.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct JobId(u64);

impl fmt::Display for JobId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "job {}", self.0)
    }
}

/// One photograph's solve to run: the core's [`PhotographSolve`] (the
/// problem, parameters, known distances and the pipeline's report), the
/// same job the command line runs.
pub type SolveRequest = PhotographSolve;

/// One photometric-stereo solve to run: the set and the scheme's settings.
#[derive(Clone, Debug)]
pub struct SetRequest {
    /// The photographs with their lights, camera, masks.
    pub problem: PhotometricProblem,
    /// The scheme's settings (validated by the solver: bad ones end in
    /// `Failed`).
    pub params: PhotometricParams,
}

/// The function a worker runs for each set ([`Worker::spawn`] uses
/// [`solve_photometric`]).
pub type SetSolveFn = Arc<
    dyn Fn(
            &PhotometricProblem,
            &PhotometricParams,
            &mut dyn SolveObserver,
        ) -> Result<PhotometricSolution, SolveError>
        + Send
        + Sync,
>;

/// The function a worker runs for each photograph's job
/// ([`Worker::spawn`] uses [`PhotographSolve::run`]; the app runs it on a
/// pool that leaves the UI a core; tests inject failures through it).
pub type SolveFn = Arc<
    dyn Fn(
            &PhotographSolve,
            &mut dyn SolveObserver,
        ) -> Result<SolvedPhotograph, PhotographSolveError>
        + Send
        + Sync,
>;

/// Called on the worker's threads after every event sent (the app passes
/// `ctx.request_repaint()`).
pub type Waker = Box<dyn Fn() + Send + Sync>;

/// What the worker reports to the UI.
#[derive(Debug)]
pub enum Event {
    /// The job began.
    Started {
        /// The job.
        job: JobId,
        /// Planned pyramid level sizes `(width, height)`, coarse to fine
        /// (one level for a warm start, empty if the parameters are
        /// invalid). The solver stops coarsening early where the object
        /// vanishes, dropping the coarsest planned sizes; the reports'
        /// `levels` count is then smaller, and `LevelResult::level` indexes
        /// the last `levels` entries of this list. With known depths each
        /// solve of the scale search runs through these levels again.
        level_sizes: Vec<(usize, usize)>,
    },
    /// After each outer iteration; dropped when the UI lags behind.
    Progress {
        /// The job.
        job: JobId,
        /// The solver's report.
        report: IterationReport,
    },
    /// After each pyramid level, coarse to fine.
    Level {
        /// The job.
        job: JobId,
        /// Depth and reprojection at the level's size.
        result: LevelResult,
    },
    /// The solve completed.
    Finished {
        /// The job.
        job: JobId,
        /// The full-resolution result with everything measured of it
        /// (the depth unit, the fit, the warnings, the report).
        solved: Box<SolvedPhotograph>,
    },
    /// A photometric-stereo set's solve completed.
    SetFinished {
        /// The job.
        job: JobId,
        /// Depth, normals, albedo and each photograph's fit.
        solution: Box<PhotometricSolution>,
    },
    /// The solver rejected the input or parameters, or panicked.
    Failed {
        /// The job.
        job: JobId,
        /// Human-readable reason (the solver's error or panic message).
        error: String,
    },
    /// The job was cancelled, superseded by a newer one, or never started.
    Cancelled {
        /// The job.
        job: JobId,
    },
}

impl Event {
    /// The job the event belongs to.
    pub fn job(&self) -> JobId {
        match self {
            Event::Started { job, .. }
            | Event::Progress { job, .. }
            | Event::Level { job, .. }
            | Event::Finished { job, .. }
            | Event::SetFinished { job, .. }
            | Event::Failed { job, .. }
            | Event::Cancelled { job } => *job,
        }
    }

    /// Whether this is the last event of its job (`Finished`,
    /// `SetFinished`, `Failed` or `Cancelled`).
    pub fn is_terminal(&self) -> bool {
        matches!(
            self,
            Event::Finished { .. }
                | Event::SetFinished { .. }
                | Event::Failed { .. }
                | Event::Cancelled { .. }
        )
    }
}

/// What the UI asks of the thread. Cancellation travels through [`Shared`]
/// instead: the thread is inside `solve()` and reads no commands then, and
/// it checks the same atomics before starting a queued job.
enum Command {
    Solve(JobId, Job),
    Shutdown,
}

/// What one job solves.
enum Job {
    /// One image (or a sum of photographs).
    Single(Box<SolveRequest>),
    /// A photometric-stereo set.
    Set(Box<SetRequest>),
}

/// State both sides read while a solve runs.
#[derive(Debug, Default)]
struct Shared {
    /// Newest submitted job id (0: none); older jobs are superseded.
    latest: AtomicU64,
    /// Every job id up to this one is cancelled.
    cancelled_up_to: AtomicU64,
    /// The worker is being dropped.
    shutdown: AtomicBool,
}

impl Shared {
    /// Whether `job` should stop: superseded, cancelled or shutting down.
    fn is_stale(&self, job: JobId) -> bool {
        self.shutdown.load(Ordering::SeqCst)
            || job.0 < self.latest.load(Ordering::SeqCst)
            || job.0 <= self.cancelled_up_to.load(Ordering::SeqCst)
    }
}

/// The thread must end: the UI side is gone or shutdown was requested.
struct Stop;

/// The sending side of the event channel, with the waker.
struct Outbox {
    events: Sender<Event>,
    waker: Waker,
    shared: Arc<Shared>,
}

impl Outbox {
    /// Sends an event that may be dropped when the channel is full.
    fn offer(&self, event: Event) -> Result<(), Stop> {
        match self.events.try_send(event) {
            Ok(()) => {
                (self.waker)();
                Ok(())
            }
            Err(TrySendError::Full(_)) => Ok(()), // the UI lags: skip this one
            Err(TrySendError::Disconnected(_)) => Err(Stop),
        }
    }

    /// Sends an event, waiting for room unless its job is stale.
    fn deliver(&self, event: Event) -> Result<(), Stop> {
        let job = event.job();
        let mut event = match self.events.try_send(event) {
            Ok(()) => {
                (self.waker)();
                return Ok(());
            }
            Err(TrySendError::Full(event)) => event,
            Err(TrySendError::Disconnected(_)) => return Err(Stop),
        };
        loop {
            if self.shared.shutdown.load(Ordering::SeqCst) {
                return Err(Stop);
            }
            if self.shared.is_stale(job) {
                return Ok(()); // the UI discards it anyway (module docs)
            }
            match self.events.send_timeout(event, SEND_POLL) {
                Ok(()) => {
                    (self.waker)();
                    return Ok(());
                }
                Err(SendTimeoutError::Timeout(back)) => event = back,
                Err(SendTimeoutError::Disconnected(_)) => return Err(Stop),
            }
        }
    }
}

/// Forwards one job's progress to the UI; runs on a rayon worker.
struct ChannelObserver<'a> {
    job: JobId,
    outbox: &'a Outbox,
    /// Set when the thread must end: stops the solve too.
    stopped: bool,
    /// The last level forwarded (its grids are shared, not copied).
    last_level: Option<LevelResult>,
}

impl<'a> ChannelObserver<'a> {
    /// A fresh observer of `job` forwarding to `outbox`: not stopped, no
    /// level forwarded yet.
    fn new(job: JobId, outbox: &'a Outbox) -> Self {
        Self {
            job,
            outbox,
            stopped: false,
            last_level: None,
        }
    }
}

impl SolveObserver for ChannelObserver<'_> {
    fn on_iteration(&mut self, report: &IterationReport) {
        let event = Event::Progress {
            job: self.job,
            report: report.clone(),
        };
        if !self.stopped && self.outbox.offer(event).is_err() {
            self.stopped = true;
        }
    }

    fn on_level(&mut self, result: &LevelResult) {
        self.last_level = Some(result.clone());
        let event = Event::Level {
            job: self.job,
            result: result.clone(),
        };
        if !self.stopped && self.outbox.deliver(event).is_err() {
            self.stopped = true;
        }
    }

    fn is_cancelled(&self) -> bool {
        self.stopped || self.outbox.shared.is_stale(self.job)
    }
}

/// The thread's side.
struct Runner {
    commands: Receiver<Command>,
    outbox: Outbox,
    solve_fn: SolveFn,
    set_fn: SetSolveFn,
}

impl Runner {
    fn run(self) {
        loop {
            let (job, request) = match self.commands.recv() {
                Ok(Command::Solve(job, request)) => (job, request),
                Ok(Command::Shutdown) | Err(_) => return,
            };
            let outcome = self
                .newest(job, request)
                .and_then(|(job, request)| match request {
                    Job::Single(request) => self.serve(job, &request),
                    Job::Set(request) => self.serve_set(job, &request),
                });
            if let Err(Stop) = outcome {
                return;
            }
        }
    }

    /// Drains queued commands, keeping the newest job; older ones are
    /// reported `Cancelled`.
    fn newest(&self, mut job: JobId, mut request: Job) -> Result<(JobId, Job), Stop> {
        loop {
            match self.commands.try_recv() {
                Ok(Command::Solve(next, next_request)) => {
                    self.outbox.deliver(Event::Cancelled { job })?;
                    (job, request) = (next, next_request);
                }
                Ok(Command::Shutdown) | Err(TryRecvError::Disconnected) => return Err(Stop),
                Err(TryRecvError::Empty) => return Ok((job, request)),
            }
        }
    }

    /// Runs one set's job and reports its end.
    fn serve_set(&self, job: JobId, request: &SetRequest) -> Result<(), Stop> {
        let sizes = planned_set_sizes(&request.problem, &request.params);
        let Some((outcome, _)) = self.run_job(job, sizes, |observer| {
            (self.set_fn)(&request.problem, &request.params, observer)
        })?
        else {
            return Ok(());
        };
        self.outbox
            .deliver(end_event(job, outcome, |solution| Event::SetFinished {
                job,
                solution: Box::new(solution),
            }))
    }

    /// Runs one job and reports its end.
    fn serve(&self, job: JobId, request: &SolveRequest) -> Result<(), Stop> {
        let sizes = planned_level_sizes(&request.problem, &request.params);
        let Some((outcome, mut observer)) = self.run_job(job, sizes, |observer| {
            (self.solve_fn)(request, observer).map_err(|e| match e {
                PhotographSolveError::Solve(e) => e,
                other => SolveError::Input(other.to_string()),
            })
        })?
        else {
            return Ok(());
        };
        if let Ok(Ok(solved)) = &outcome
            && solved.depth_unit.as_ref().is_some_and(|u| u.fit.is_some())
            && let Some(level) = rescaled_level(observer.last_level.take(), &solved.solution)
        {
            // The search scaled the last solve's depth onto the known
            // distances: the UI shows what `Finished` holds.
            self.outbox.deliver(Event::Level { job, result: level })?;
        }
        self.outbox
            .deliver(end_event(job, outcome, |solved| Event::Finished {
                job,
                solved: Box::new(solved),
            }))
    }

    /// Begins a job (`Ok(None)`: superseded before it began) and runs
    /// `solve` with its observer, a panic caught; `Err(Stop)` on shutdown or
    /// when the observer stopped, else the outcome and the observer.
    fn run_job<T>(
        &self,
        job: JobId,
        level_sizes: Vec<(usize, usize)>,
        solve: impl FnOnce(&mut ChannelObserver<'_>) -> Result<T, SolveError>,
    ) -> Result<Option<(Outcome<T>, ChannelObserver<'_>)>, Stop> {
        if !self.begin(job, level_sizes)? {
            return Ok(None);
        }
        let mut observer = ChannelObserver::new(job, &self.outbox);
        let outcome = panic::catch_unwind(AssertUnwindSafe(|| solve(&mut observer)));
        if observer.stopped || self.outbox.shared.shutdown.load(Ordering::SeqCst) {
            return Err(Stop);
        }
        Ok(Some((outcome, observer)))
    }

    /// A job's start: `Err(Stop)` on shutdown, `Ok(false)` for a job
    /// superseded before it began (`Cancelled` sent), else `Started` sent
    /// with the planned level sizes and `Ok(true)`.
    fn begin(&self, job: JobId, level_sizes: Vec<(usize, usize)>) -> Result<bool, Stop> {
        let shared = &self.outbox.shared;
        if shared.shutdown.load(Ordering::SeqCst) {
            return Err(Stop);
        }
        if shared.is_stale(job) {
            self.outbox.deliver(Event::Cancelled { job })?;
            return Ok(false);
        }
        self.outbox.deliver(Event::Started { job, level_sizes })?;
        Ok(true)
    }
}

/// How a job's solve ended: a result, or the panic it raised.
type Outcome<T> = std::thread::Result<Result<T, SolveError>>;

/// The event that ends a job: `finished` of its result, `Cancelled`, or
/// `Failed` with the error or the panic's message.
fn end_event<T>(job: JobId, outcome: Outcome<T>, finished: impl FnOnce(T) -> Event) -> Event {
    match outcome {
        Ok(Ok(result)) => finished(result),
        Ok(Err(SolveError::Cancelled)) => Event::Cancelled { job },
        Ok(Err(error)) => Event::Failed {
            job,
            error: error.to_string(),
        },
        Err(payload) => Event::Failed {
            job,
            error: format!("the solver panicked: {}", panic_message(&*payload)),
        },
    }
}

/// The last level sent with the finished depth in place of its own, when
/// the two are of one size and differ (a known-depth search rescales the
/// last solve's depth after it was sent); `None` otherwise.
fn rescaled_level(last: Option<LevelResult>, solution: &Solution) -> Option<LevelResult> {
    let last = last?;
    let same = last.depth.size() == solution.depth.size()
        && last
            .depth
            .as_slice()
            .iter()
            .zip(solution.depth.as_slice())
            .all(|(a, b)| a == b || (a.is_nan() && b.is_nan()));
    (last.depth.size() == solution.depth.size() && !same).then(|| LevelResult {
        depth: Arc::new(solution.depth.clone()),
        ..last
    })
}

/// The level sizes the solver will plan, coarse to fine (see
/// [`Event::Started`]); empty for invalid parameters, on which the pyramid
/// code would not terminate (e.g. `eta >= 1`).
fn planned_level_sizes(problem: &Problem, params: &SolverParams) -> Vec<(usize, usize)> {
    if params.validate().is_err() {
        return Vec::new();
    }
    let (width, height) = problem.image.size();
    match params.initial_depth {
        InitialDepth::Map(_) => return vec![(width, height)],
        // The fast-marching start arrives as a level of its own.
        InitialDepth::FastMarching => return vec![(width, height); 2],
        _ => {}
    }
    let mut sizes = pyramid::level_sizes(width, height, params.eta, params.min_level_side);
    sizes.reverse();
    sizes
}

/// The level sizes a set's solve plans, coarse to fine (its pyramid
/// halves each side down to `min_side`); empty for a set without
/// photographs. The solver may start below the coarsest (a level
/// that cannot hold the object) and report fewer.
fn planned_set_sizes(
    problem: &PhotometricProblem,
    params: &PhotometricParams,
) -> Vec<(usize, usize)> {
    let Some(first) = problem.photos.first() else {
        return Vec::new();
    };
    let (width, height) = first.image.size();
    if width < 3 || height < 3 {
        return Vec::new();
    }
    let mut sizes = sfs_core::solver::photometric::level_sizes(width, height, params);
    sizes.reverse();
    sizes
}

/// The message of a panic payload (`panic!` gives `&str` or `String`).
fn panic_message(payload: &(dyn Any + Send)) -> &str {
    if let Some(message) = payload.downcast_ref::<&str>() {
        message
    } else if let Some(message) = payload.downcast_ref::<String>() {
        message
    } else {
        "(no message)"
    }
}

/// The UI's handle on the solver thread. Dropping it stops and joins the
/// thread.
pub struct Worker {
    commands: Sender<Command>,
    events: Receiver<Event>,
    shared: Arc<Shared>,
    /// The newest job id handed out (0: none).
    last_id: u64,
    /// The newest job, until its terminal event has been received here.
    unfinished: Option<JobId>,
    thread: Option<JoinHandle<()>>,
}

impl Worker {
    /// Starts the thread `sfs-solver` running [`sfs_core::solver::solve`]
    /// (and [`solve_photometric`] for sets).
    pub fn spawn(waker: Waker) -> io::Result<Self> {
        Self::spawn_with(waker, Arc::new(|job, observer| job.run(observer)))
    }

    /// Starts the thread with another solve function (a different
    /// reflectance model, or fault injection in tests); sets run
    /// [`solve_photometric`].
    pub fn spawn_with(waker: Waker, solve_fn: SolveFn) -> io::Result<Self> {
        Self::spawn_with_set(waker, solve_fn, Arc::new(solve_photometric))
    }

    /// Starts the thread with a solve function for single images and one
    /// for photometric-stereo sets (the app runs both on a pool that
    /// leaves the UI a core).
    pub fn spawn_with_set(waker: Waker, solve_fn: SolveFn, set_fn: SetSolveFn) -> io::Result<Self> {
        let (command_sender, command_receiver) = bounded(COMMAND_CAPACITY);
        let (event_sender, event_receiver) = bounded(EVENT_CAPACITY);
        let shared = Arc::new(Shared::default());
        let runner = Runner {
            commands: command_receiver,
            outbox: Outbox {
                events: event_sender,
                waker,
                shared: Arc::clone(&shared),
            },
            solve_fn,
            set_fn,
        };
        let thread = thread::Builder::new()
            .name("sfs-solver".into())
            .spawn(move || runner.run())?;
        Ok(Self {
            commands: command_sender,
            events: event_receiver,
            shared,
            last_id: 0,
            unfinished: None,
            thread: Some(thread),
        })
    }

    /// Queues a solve and returns its id; supersedes every older job (the
    /// running one stops at its next SOR sweep). Blocks only while 64
    /// commands are queued, until the thread (which drops stale work
    /// promptly) takes them. If the thread has stopped, draining reports
    /// `Failed` for the job.
    pub fn submit(&mut self, request: SolveRequest) -> JobId {
        self.send_job(Job::Single(Box::new(request)))
    }

    /// Queues a photometric-stereo set's solve, as [`Self::submit`] queues
    /// one image's (the same ids, superseding and cancellation); it ends
    /// with [`Event::SetFinished`].
    pub fn submit_set(&mut self, request: SetRequest) -> JobId {
        self.send_job(Job::Set(Box::new(request)))
    }

    fn send_job(&mut self, request: Job) -> JobId {
        self.last_id += 1;
        let job = JobId(self.last_id);
        self.shared.latest.store(job.0, Ordering::SeqCst);
        self.unfinished = Some(job);
        if self.commands.send(Command::Solve(job, request)).is_err() {
            // The thread has ended; `thread_stopped` turns the closed event
            // channel into `Failed` for `unfinished`, which is this job.
        }
        job
    }

    /// Cancels `job` (and every older one) if it has not ended: it reports
    /// `Cancelled`, or still `Finished`/`Failed` if it ended first. Ids not
    /// handed out yet are ignored.
    pub fn cancel(&self, job: JobId) {
        if job.0 <= self.last_id {
            self.shared
                .cancelled_up_to
                .fetch_max(job.0, Ordering::SeqCst);
        }
    }

    /// The newest submitted job (`None` before the first submit). Events of
    /// other jobs are stale.
    pub fn latest_job(&self) -> Option<JobId> {
        (self.last_id > 0).then_some(JobId(self.last_id))
    }

    /// Whether the newest job's terminal event has not been received yet.
    pub fn is_busy(&self) -> bool {
        self.unfinished.is_some()
    }

    /// Receives pending events, in order, until none is pending or `budget`
    /// has passed since this call (time spent by the caller between items
    /// counts). The first pending event is always yielded.
    pub fn drain(&mut self, budget: Duration) -> Drain<'_> {
        Drain {
            worker: self,
            started: Instant::now(),
            budget,
            yielded: false,
        }
    }

    /// Waits up to `timeout` for the next event (for headless use and tests;
    /// `Duration::ZERO` only takes a pending one).
    pub fn recv_timeout(&mut self, timeout: Duration) -> Option<Event> {
        let event = match self.events.recv_timeout(timeout) {
            Ok(event) => event,
            Err(RecvTimeoutError::Timeout) => return None,
            Err(RecvTimeoutError::Disconnected) => self.thread_stopped()?,
        };
        if event.is_terminal() && Some(event.job()) == self.unfinished {
            self.unfinished = None;
        }
        Some(event)
    }

    /// The event channel closed while this handle lives (only a bug ends the
    /// thread early): `Failed` for the newest job, once.
    fn thread_stopped(&self) -> Option<Event> {
        self.unfinished.map(|job| Event::Failed {
            job,
            error: THREAD_STOPPED.into(),
        })
    }
}

impl Drop for Worker {
    fn drop(&mut self) {
        self.shared.shutdown.store(true, Ordering::SeqCst);
        match self.commands.try_send(Command::Shutdown) {
            // Full: the thread is busy and sees the flag at its next poll.
            // Disconnected: it has already ended.
            Ok(()) | Err(TrySendError::Full(_)) | Err(TrySendError::Disconnected(_)) => {}
        }
        if let Some(thread) = self.thread.take() {
            join_within(thread, SHUTDOWN_WAIT);
        }
    }
}

/// How long dropping a [`Worker`] waits for its thread: the solver polls
/// cancellation every few milliseconds, so this is only reached when the
/// thread is stuck in work that cannot poll (a very large allocation).
pub const SHUTDOWN_WAIT: Duration = Duration::from_secs(2);

/// Joins `thread` if it ends within `wait`; otherwise leaves it running
/// detached, so a closing window never waits for it (the process ends
/// with `main`). A panic inside the thread has been reported by the hook.
pub fn join_within(thread: std::thread::JoinHandle<()>, wait: Duration) {
    let deadline = Instant::now() + wait;
    while !thread.is_finished() && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(2));
    }
    if thread.is_finished() {
        let _ = thread.join();
    }
}

/// Iterator returned by [`Worker::drain`].
pub struct Drain<'a> {
    worker: &'a mut Worker,
    started: Instant,
    budget: Duration,
    yielded: bool,
}

impl Iterator for Drain<'_> {
    type Item = Event;

    fn next(&mut self) -> Option<Event> {
        if self.yielded && self.started.elapsed() >= self.budget {
            return None;
        }
        let event = self.worker.recv_timeout(Duration::ZERO)?;
        self.yielded = true;
        Some(event)
    }
}

#[cfg(test)]
mod tests;
