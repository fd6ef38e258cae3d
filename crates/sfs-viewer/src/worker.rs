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

use sfs_core::light::PointLight;
use sfs_core::params::{InitialDepth, SolverParams};
use sfs_core::solver::calibrate::KnownDepth;
use sfs_core::solver::depth_unit::{self, DepthUnit, DistanceCues};
use sfs_core::solver::photometric::{
    PhotometricParams, PhotometricProblem, PhotometricSolution, solve_photometric,
};
use sfs_core::solver::pyramid;
use sfs_core::solver::{
    IterationReport, LevelResult, Method, Problem, Solution, SolveError, SolveObserver,
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

/// One solve to run: the problem and the parameters.
#[derive(Clone, Debug)]
pub struct SolveRequest {
    /// Image, camera, masks.
    pub problem: Problem,
    /// Solver parameters (validated by the solver: bad ones end in `Failed`).
    pub params: SolverParams,
    /// Decide the intensity scale (no scale given; see
    /// [`sfs_core::solver::depth_unit`]): with lights off the centre the
    /// job runs [`depth_unit::solve_photograph`] instead of the
    /// [`SolveFn`]. Ignored when [`Self::known_depths`] or
    /// [`Self::distance`] set the scale.
    pub estimate_scale: bool,
    /// Distances the user knows, in pixels of `problem.image` (the working
    /// size). Not empty: the job runs [`depth_unit::solve_photograph`] with
    /// the linearised scheme, which moves the intensity scale until the
    /// depth meets them, instead of the [`SolveFn`].
    pub known_depths: Vec<KnownDepth>,
    /// The object's distance (median depth) the user gives: as
    /// [`Self::known_depths`], with the median.
    pub distance: Option<f64>,
    /// The rig's aimed lights (`photo::PhotoReport::rig_lights`), a cue to
    /// the distance.
    pub rig_lights: Vec<PointLight>,
}

impl SolveRequest {
    /// A plain request: the problem and parameters, the scale estimated
    /// where `estimate_scale`, no distance given, no rig.
    pub fn new(problem: Problem, params: SolverParams, estimate_scale: bool) -> Self {
        Self {
            problem,
            params,
            estimate_scale,
            known_depths: Vec::new(),
            distance: None,
            rig_lights: Vec::new(),
        }
    }

    /// Whether the job decides its depth unit ([`depth_unit::solve_photograph`])
    /// rather than running the [`SolveFn`].
    pub fn decides_depth_unit(&self) -> bool {
        !self.known_depths.is_empty()
            || self.distance.is_some()
            || (self.estimate_scale && !self.problem.light_is_centred())
    }
}

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

/// The function a worker runs for each job without known depths
/// ([`Worker::spawn`] uses [`sfs_core::solver::solve`]; tests inject
/// failures through it).
pub type SolveFn = Arc<
    dyn Fn(&Problem, &SolverParams, &mut dyn SolveObserver) -> Result<Solution, SolveError>
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
        /// The full-resolution result.
        solution: Box<Solution>,
        /// The depth unit the job decided, and how it met known depths or
        /// the object's distance (`None` when it decided none).
        depth_unit: Option<Box<DepthUnit>>,
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
        let shared = &self.outbox.shared;
        if !self.begin(job, planned_set_sizes(&request.problem, &request.params))? {
            return Ok(());
        }
        let mut observer = ChannelObserver {
            job,
            outbox: &self.outbox,
            stopped: false,
            last_level: None,
        };
        let outcome = panic::catch_unwind(AssertUnwindSafe(|| {
            (self.set_fn)(&request.problem, &request.params, &mut observer)
        }));
        if observer.stopped || shared.shutdown.load(Ordering::SeqCst) {
            return Err(Stop);
        }
        self.outbox
            .deliver(end_event(job, outcome, |solution| Event::SetFinished {
                job,
                solution: Box::new(solution),
            }))
    }

    /// Runs one job and reports its end.
    fn serve(&self, job: JobId, request: &SolveRequest) -> Result<(), Stop> {
        let shared = &self.outbox.shared;
        if !self.begin(job, planned_level_sizes(&request.problem, &request.params))? {
            return Ok(());
        }
        let mut observer = ChannelObserver {
            job,
            outbox: &self.outbox,
            stopped: false,
            last_level: None,
        };
        let outcome = panic::catch_unwind(AssertUnwindSafe(|| {
            if request.decides_depth_unit() {
                let mut problem = request.problem.clone();
                let cues = DistanceCues {
                    known_depths: request.known_depths.clone(),
                    distance: request.distance,
                    scale_given: !request.estimate_scale,
                    rig_lights: request.rig_lights.clone(),
                };
                let (solution, unit) = depth_unit::solve_photograph(
                    &mut problem,
                    &request.params,
                    &Method::Linearised,
                    &cues,
                    &mut observer,
                )?;
                return Ok((solution, Some(Box::new(unit))));
            }
            (self.solve_fn)(&request.problem, &request.params, &mut observer).map(|s| (s, None))
        }));
        if observer.stopped || shared.shutdown.load(Ordering::SeqCst) {
            return Err(Stop);
        }
        if let Ok(Ok((solution, Some(unit)))) = &outcome
            && unit.fit.is_some()
            && let Some(level) = rescaled_level(observer.last_level.take(), solution)
        {
            // The search scaled the last solve's depth onto the known
            // distances: the UI shows what `Finished` holds.
            self.outbox.deliver(Event::Level { job, result: level })?;
        }
        self.outbox
            .deliver(end_event(job, outcome, |(solution, depth_unit)| {
                Event::Finished {
                    job,
                    solution: Box::new(solution),
                    depth_unit,
                }
            }))
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

/// The event that ends a job: `finished` of its result, `Cancelled`, or
/// `Failed` with the error or the panic's message.
fn end_event<T>(
    job: JobId,
    outcome: std::thread::Result<Result<T, SolveError>>,
    finished: impl FnOnce(T) -> Event,
) -> Event {
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
        Self::spawn_with(waker, Arc::new(sfs_core::solver::solve))
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
mod tests {

    #[test]
    fn join_within_leaves_a_stuck_thread_behind() {
        let (release, stuck_on) = crossbeam_channel::bounded::<()>(0);
        let stuck = std::thread::spawn(move || {
            let _ = stuck_on.recv();
        });
        // Would never return if it joined: the thread waits for `release`.
        join_within(stuck, Duration::from_millis(20));
        drop(release);
        let quick = std::thread::spawn(|| {});
        join_within(quick, SHUTDOWN_WAIT);
    }
    use std::sync::atomic::AtomicUsize;

    use sfs_core::camera::Intrinsics;
    use sfs_core::grid::Grid;
    use sfs_core::material::Material;
    use sfs_core::params::ReflectanceChoice;
    use sfs_core::scene::sombrero::sombrero;

    use super::*;

    /// Generous: a wait that fails means a lost event, not a slow machine.
    const PATIENCE: Duration = Duration::from_secs(60);

    fn sombrero_request(side: usize) -> SolveRequest {
        let scene = sombrero(side, side);
        let problem = Problem {
            image: scene.image,
            camera: scene.camera,
            intensity_scale: scene.intensity_scale,
            object_mask: Some(scene.object_mask),
            confidence: None,
            lights: Vec::new(),
        };
        // The paper's constant start: the whole pyramid, many levels.
        let params = SolverParams {
            initial_depth: InitialDepth::FromImage,
            ..SolverParams::default()
        };
        SolveRequest {
            problem,
            params,
            estimate_scale: false,
            known_depths: Vec::new(),
            distance: None,
            rig_lights: Vec::new(),
        }
    }

    /// The 64x64 Sombrero (light at the optical centre, default parameters)
    /// with one known distance at its pixel (40, 24): 1.5 times the true
    /// depth there, so the scale must move.
    fn known_depth_request(distance_factor: f64) -> (SolveRequest, KnownDepth) {
        let scene = sfs_core::scene::sombrero::sombrero_lit(64, 64, &[]);
        let (column, row) = (40, 24);
        let point = KnownDepth {
            column_px: column as f64,
            row_px: row as f64,
            depth: distance_factor * scene.depth_gt.at(column, row),
        };
        let request = SolveRequest {
            problem: Problem {
                image: scene.image,
                camera: scene.camera,
                intensity_scale: scene.intensity_scale,
                object_mask: Some(scene.object_mask),
                confidence: None,
                lights: Vec::new(),
            },
            params: SolverParams::default(),
            estimate_scale: true,
            known_depths: vec![point],
            distance: None,
            rig_lights: Vec::new(),
        };
        (request, point)
    }

    /// A 1x1 image: the solver rejects it.
    fn tiny_request() -> SolveRequest {
        let mut request = sombrero_request(3);
        request.problem.image = Grid::filled(1, 1, 0.5);
        request.problem.camera = Intrinsics::centred(1.0, 1, 1);
        request.problem.object_mask = None;
        request
    }

    fn spawn_counting() -> (Worker, Arc<AtomicUsize>) {
        let wakes = Arc::new(AtomicUsize::new(0));
        let counter = Arc::clone(&wakes);
        let waker = Box::new(move || {
            counter.fetch_add(1, Ordering::SeqCst);
        });
        (Worker::spawn(waker).expect("spawn"), wakes)
    }

    fn next_event(worker: &mut Worker) -> Event {
        match worker.recv_timeout(PATIENCE) {
            Some(event) => event,
            None => panic!("no event within {PATIENCE:?}"),
        }
    }

    /// Events until the terminal event of `job` (inclusive).
    fn events_until_end(worker: &mut Worker, job: JobId) -> Vec<Event> {
        let mut events = vec![next_event(worker)];
        while !events
            .last()
            .is_some_and(|e| e.is_terminal() && e.job() == job)
        {
            events.push(next_event(worker));
        }
        events
    }

    fn wait_for_progress(worker: &mut Worker, job: JobId) {
        loop {
            let event = next_event(worker);
            assert!(
                event.job() == job && !event.is_terminal(),
                "{}",
                kind(Some(&event))
            );
            if let Event::Progress { .. } = event {
                return;
            }
        }
    }

    /// The variant and job, for messages (events hold whole depth maps).
    fn kind(event: Option<&Event>) -> String {
        let Some(event) = event else {
            return "nothing".into();
        };
        let name = match event {
            Event::Started { .. } => "Started",
            Event::Progress { .. } => "Progress",
            Event::Level { .. } => "Level",
            Event::Finished { .. } => "Finished",
            Event::SetFinished { .. } => "SetFinished",
            Event::Failed { .. } => "Failed",
            Event::Cancelled { .. } => "Cancelled",
        };
        format!("{name} of {}", event.job())
    }

    fn failure(event: Option<&Event>) -> &str {
        match event {
            Some(Event::Failed { error, .. }) => error,
            other => panic!("expected Failed, got {}", kind(other)),
        }
    }

    fn finished(event: Option<&Event>) -> bool {
        matches!(event, Some(Event::Finished { .. }))
    }

    #[test]
    fn small_solve_reports_levels_coarse_to_fine_and_finishes() {
        let (mut worker, wakes) = spawn_counting();
        assert!(worker.latest_job().is_none() && !worker.is_busy());
        let job = worker.submit(sombrero_request(32));
        assert!(worker.latest_job() == Some(job) && worker.is_busy());
        let mut events = Vec::new();
        let deadline = Instant::now() + PATIENCE;
        while worker.is_busy() {
            assert!(Instant::now() < deadline, "no Finished within {PATIENCE:?}");
            events.extend(worker.drain(Duration::from_millis(5)));
            thread::sleep(Duration::from_millis(1));
        }
        assert!(events.iter().all(|e| e.job() == job));
        let Some(Event::Started { level_sizes, .. }) = events.first() else {
            panic!("first event is {}", kind(events.first()));
        };
        assert!(level_sizes.len() > 1 && level_sizes.last() == Some(&(32, 32)));
        assert!(
            level_sizes
                .windows(2)
                .all(|p| p[0].0 < p[1].0 && p[0].1 < p[1].1)
        );
        let levels: Vec<&LevelResult> = events
            .iter()
            .filter_map(|e| match e {
                Event::Level { result, .. } => Some(result),
                _ => None,
            })
            .collect();
        assert_eq!(levels.len(), level_sizes.len());
        for (index, (result, size)) in levels.iter().zip(level_sizes).enumerate() {
            assert_eq!((result.level, result.levels), (index, level_sizes.len()));
            assert_eq!(result.depth.size(), *size);
        }
        assert!(events.iter().any(|e| matches!(e, Event::Progress { .. })));
        let Some(Event::Finished { solution, .. }) = events.last() else {
            panic!("last event is {}", kind(events.last()));
        };
        assert_eq!(solution.depth.size(), (32, 32));
        assert_eq!(solution.levels.len(), level_sizes.len());
        assert_eq!(events.iter().filter(|e| e.is_terminal()).count(), 1);
        // The waker runs just after each send: let it catch up.
        while wakes.load(Ordering::SeqCst) < events.len() {
            assert!(Instant::now() < deadline, "waker called too rarely");
            thread::sleep(Duration::from_millis(1));
        }
        assert!(worker.drain(Duration::from_secs(1)).next().is_none());
    }

    #[test]
    fn a_known_depth_sets_the_scale_and_the_fit_reaches_the_ui() {
        let (mut worker, _) = spawn_counting();
        let (request, point) = known_depth_request(1.5);
        let job = worker.submit(request);
        let events = events_until_end(&mut worker, job);
        let Some(Event::Finished {
            solution,
            depth_unit,
            ..
        }) = events.last()
        else {
            panic!("last event is {}", kind(events.last()));
        };
        let known_depth_fit = depth_unit.as_ref().and_then(|u| u.fit.as_ref());
        let (c, r) = (point.column_px as usize, point.row_px as usize);
        let solved = *solution.depth.at(c, r);
        assert!(
            ((solved - point.depth) / point.depth).abs() < 5e-3,
            "solved {solved}, given {}",
            point.depth
        );
        let fit = known_depth_fit.expect("the fit is reported");
        assert_eq!(fit.points.len(), 1);
        assert!(fit.converged && fit.solves >= 1, "{fit:?}");
        assert!(fit.points[0].relative_residual.abs() < 5e-3, "{fit:?}");
        // Depth goes as sqrt(s): 1.5 times the depth, about 2.25 times s = 2.
        assert!(
            (3.5..5.5).contains(&fit.intensity_scale),
            "{}",
            fit.intensity_scale
        );
        // The last level on screen is the finished depth.
        let last_level = events
            .iter()
            .rev()
            .find_map(|e| match e {
                Event::Level { result, .. } => Some(result),
                _ => None,
            })
            .expect("levels streamed");
        assert_eq!(*last_level.depth, solution.depth);
        // Without known depths there is no fit.
        let job = worker.submit(sombrero_request(32));
        let events = events_until_end(&mut worker, job);
        assert!(matches!(
            events.last(),
            Some(Event::Finished {
                depth_unit: None,
                ..
            })
        ));
    }

    /// The finished solution of `job`'s events, which must end with it.
    fn finished_solution(events: &[Event]) -> &Solution {
        match events.last() {
            Some(Event::Finished { solution, .. }) => solution,
            other => panic!("last event is {}", kind(other)),
        }
    }

    /// Checks a fit of `reflectance auto` and that the solve used its
    /// material.
    fn assert_fitted(solution: &Solution) {
        let fit = solution
            .material_fit
            .as_ref()
            .expect("reflectance auto reports its fit");
        assert_eq!(
            fit.trials.len(),
            sfs_core::solver::material_fit::candidates().len()
        );
        assert_eq!(fit.trials[0].material, fit.best);
        assert_eq!(solution.material, fit.material);
        assert!(!fit.summary.is_empty());
    }

    #[test]
    fn reflectance_auto_fits_the_material_and_the_fit_reaches_the_ui() {
        let (mut worker, _) = spawn_counting();
        let mut request = sombrero_request(32);
        request.params.reflectance = ReflectanceChoice::Auto;
        let job = worker.submit(request);
        let events = events_until_end(&mut worker, job);
        let solution = finished_solution(&events);
        assert_fitted(solution);
        assert_eq!(solution.depth.size(), (32, 32));
        // A given material: no fit.
        let mut request = sombrero_request(32);
        request.params.reflectance = ReflectanceChoice::OrenNayar;
        request.params.roughness_rad = 0.45;
        let job = worker.submit(request);
        let events = events_until_end(&mut worker, job);
        let solution = finished_solution(&events);
        assert!(solution.material_fit.is_none());
        assert_eq!(
            solution.material,
            Material::OrenNayar {
                roughness_rad: 0.45
            }
        );
        // With a known distance: fitted before the search, which meets it.
        let (mut request, point) = known_depth_request(1.5);
        request.params.reflectance = ReflectanceChoice::Auto;
        let job = worker.submit(request);
        let events = events_until_end(&mut worker, job);
        let Some(Event::Finished {
            depth_unit: Some(unit),
            ..
        }) = events.last()
        else {
            panic!("last event is {} without a fit", kind(events.last()));
        };
        let fit = unit.fit.as_ref().expect("the fit is reported");
        assert!(fit.converged, "{fit:?}");
        let solution = finished_solution(&events);
        assert_fitted(solution);
        let solved = *solution
            .depth
            .at(point.column_px as usize, point.row_px as usize);
        assert!(
            ((solved - point.depth) / point.depth).abs() < 5e-3,
            "solved {solved}, given {}",
            point.depth
        );
        // A light off the centre, scale estimated: as Lambertian, then the
        // material is fitted at the estimated scale.
        let a = 40f64.to_radians();
        let light = sfs_core::light::PointLight {
            position: [2.0 * a.sin(), 0.0, 2.0 * (1.0 - a.cos())],
            ..sfs_core::light::PointLight::CENTRED
        };
        let scene = sfs_core::scene::sombrero::sombrero_lit(48, 48, &[light]);
        let request = SolveRequest {
            problem: Problem {
                image: scene.image,
                camera: scene.camera,
                intensity_scale: 1.0,
                object_mask: Some(scene.object_mask),
                confidence: None,
                lights: vec![light],
            },
            params: SolverParams {
                reflectance: ReflectanceChoice::Auto,
                ..SolverParams::default()
            },
            estimate_scale: true,
            known_depths: Vec::new(),
            distance: None,
            rig_lights: Vec::new(),
        };
        let job = worker.submit(request);
        let events = events_until_end(&mut worker, job);
        assert!(matches!(
            events.last(),
            Some(Event::Finished {
                depth_unit: Some(_),
                ..
            })
        ));
        assert_fitted(finished_solution(&events));
    }

    #[test]
    fn a_non_positive_known_depth_fails_the_job_without_a_panic() {
        let (mut worker, _) = spawn_counting();
        for distance in [0.0, -1.0, f64::NAN] {
            let (mut request, _) = known_depth_request(1.0);
            request.known_depths[0].depth = distance;
            let job = worker.submit(request);
            let error = failure(events_until_end(&mut worker, job).last()).to_owned();
            assert!(error.contains("must be positive"), "{error}");
            assert!(!error.contains("panicked"), "{error}");
        }
        // Off the image: refused by the search, and the worker lives on.
        let (mut request, _) = known_depth_request(1.0);
        request.known_depths[0].column_px = 640.0;
        let job = worker.submit(request);
        let error = failure(events_until_end(&mut worker, job).last()).to_owned();
        assert!(error.contains("not on the solved surface"), "{error}");
        let (request, _) = known_depth_request(1.0);
        let job = worker.submit(request);
        assert!(finished(events_until_end(&mut worker, job).last()));
    }

    #[test]
    fn cancel_stops_a_running_solve() {
        let (mut worker, _) = spawn_counting();
        let job = worker.submit(sombrero_request(192));
        wait_for_progress(&mut worker, job);
        worker.cancel(job);
        let events = events_until_end(&mut worker, job);
        assert!(matches!(events.last(), Some(Event::Cancelled { .. })));
        assert!(events.iter().all(|e| e.job() == job && !finished(Some(e))));
        assert!(!worker.is_busy());
    }

    #[test]
    fn a_newer_job_supersedes_an_older_one() {
        let (mut worker, _) = spawn_counting();
        let old = worker.submit(sombrero_request(192));
        let new = worker.submit(sombrero_request(32));
        assert!(new > old && worker.latest_job() == Some(new));
        let events = events_until_end(&mut worker, new);
        assert!(finished(events.last()));
        // The old job may or may not have started before the new one came.
        let of_old: Vec<&Event> = events.iter().filter(|e| e.job() == old).collect();
        assert!(matches!(of_old.last(), Some(Event::Cancelled { .. })));
        assert_eq!(of_old.iter().filter(|e| e.is_terminal()).count(), 1);
        let new_started = events
            .iter()
            .position(|e| e.job() == new && matches!(e, Event::Started { .. }))
            .expect("new job started");
        assert!(events[new_started..].iter().all(|e| e.job() == new));
    }

    struct PanicOnIteration;

    impl SolveObserver for PanicOnIteration {
        fn on_iteration(&mut self, report: &IterationReport) {
            panic!("injected fault at level {}", report.level);
        }
    }

    #[test]
    fn errors_and_panics_fail_the_job_and_the_worker_lives_on() {
        let calls = Arc::new(AtomicUsize::new(0));
        let counter = Arc::clone(&calls);
        let solve_fn: SolveFn = Arc::new(
            move |problem: &Problem, params: &SolverParams, observer: &mut dyn SolveObserver| {
                if counter.fetch_add(1, Ordering::SeqCst) == 0 {
                    // Panics inside the solve, on a rayon worker.
                    sfs_core::solver::solve(problem, params, &mut PanicOnIteration)
                } else {
                    sfs_core::solver::solve(problem, params, observer)
                }
            },
        );
        let mut worker = Worker::spawn_with(Box::new(|| {}), solve_fn).expect("spawn");
        let job = worker.submit(sombrero_request(32));
        let error = failure(events_until_end(&mut worker, job).last()).to_owned();
        assert!(error.contains("injected fault at level 0"), "{error}");
        let job = worker.submit(tiny_request());
        let error = failure(events_until_end(&mut worker, job).last()).to_owned();
        assert!(error.contains("1x1"), "{error}");
        // Invalid parameters: no level sizes (the pyramid would not end).
        let mut request = sombrero_request(32);
        request.params.eta = 1.0;
        let job = worker.submit(request);
        let events = events_until_end(&mut worker, job);
        let Event::Started { level_sizes, .. } = &events[0] else {
            panic!("first event is {}", kind(Some(&events[0])));
        };
        assert!(level_sizes.is_empty());
        assert!(failure(events.last()).contains("eta"));
        let job = worker.submit(sombrero_request(32));
        assert!(finished(events_until_end(&mut worker, job).last()));
        assert_eq!(calls.load(Ordering::SeqCst), 4);
    }

    #[test]
    fn dropping_the_worker_during_a_solve_joins_the_thread() {
        let (mut worker, _) = spawn_counting();
        let job = worker.submit(sombrero_request(192));
        wait_for_progress(&mut worker, job);
        let (done_sender, done) = bounded(1);
        thread::spawn(move || {
            drop(worker);
            done_sender.send(()).expect("test receiver alive");
        });
        assert!(done.recv_timeout(PATIENCE).is_ok(), "drop hung");
    }

    #[test]
    fn a_ui_that_does_not_drain_cannot_block_submit_forever() {
        let (worker, _) = spawn_counting();
        // Far more jobs than both channels hold, submitted without draining:
        // the thread drops stale events instead of waiting for the UI.
        let (back_sender, back) = bounded(1);
        thread::spawn(move || {
            let mut worker = worker;
            let mut last = None;
            for _ in 0..4 * (COMMAND_CAPACITY + EVENT_CAPACITY) {
                last = Some(worker.submit(tiny_request()));
            }
            back_sender
                .send((worker, last))
                .expect("test receiver alive");
        });
        let Ok((mut worker, Some(last))) = back.recv_timeout(PATIENCE) else {
            panic!("submit blocked for {PATIENCE:?}");
        };
        failure(events_until_end(&mut worker, last).last());
        assert!(!worker.is_busy());
    }

    #[test]
    fn drain_yields_at_least_one_event_and_stops_at_the_budget() {
        let (mut worker, _) = spawn_counting();
        let job = worker.submit(tiny_request());
        let deadline = Instant::now() + PATIENCE;
        while worker.events.len() < 2 {
            assert!(Instant::now() < deadline, "Started and Failed did not come");
            thread::sleep(Duration::from_millis(1));
        }
        let first: Vec<Event> = worker.drain(Duration::ZERO).collect();
        assert!(matches!(first[..], [Event::Started { .. }]) && worker.is_busy());
        let rest: Vec<Event> = worker.drain(Duration::from_secs(1)).collect();
        assert!(rest.len() == 1 && rest[0].job() == job);
        failure(rest.first());
        assert!(!worker.is_busy());
    }

    /// The synthetic set written as files, read through the photo
    /// pipeline as the viewer reads it.
    fn set_request(dir: &std::path::Path) -> SetRequest {
        let images = crate::test_sets::write_set(dir);
        let input = sfs_core::photo::PhotoInput {
            camera: sfs_core::photo::CameraSpec::File(dir.join("scene.json")),
            lights: sfs_core::photo::LightSpec::CameraFileOrCentred,
            object_mask: Some(dir.join("mask.png")),
            photometric_stereo: true,
            images,
            ..sfs_core::photo::PhotoInput::new(dir.join("led1.png"))
        };
        let prepared = sfs_core::photo::prepare(&input).unwrap_or_else(|e| panic!("{e}"));
        let problem = sfs_core::photo::photometric_problem(&prepared, &input)
            .unwrap_or_else(|e| panic!("{e}"));
        SetRequest {
            problem,
            params: PhotometricParams::default(),
        }
    }

    #[test]
    fn a_set_streams_its_levels_and_finishes_with_depth_normals_and_albedo() {
        let dir = tempfile::tempdir().expect("temp dir");
        let request = set_request(dir.path());
        assert_eq!(request.problem.photos.len(), crate::test_sets::PHOTOS);
        let (mut worker, _) = spawn_counting();
        let job = worker.submit_set(request.clone());
        let events = events_until_end(&mut worker, job);
        let Some(Event::Started { level_sizes, .. }) = events.first() else {
            panic!("first event is {}", kind(events.first()));
        };
        let side = crate::test_sets::SIDE;
        assert_eq!(level_sizes.last(), Some(&(side, side)));
        let levels: Vec<&LevelResult> = events
            .iter()
            .filter_map(|e| match e {
                Event::Level { result, .. } => Some(result),
                _ => None,
            })
            .collect();
        assert!(!levels.is_empty(), "no level streamed");
        assert!(levels.windows(2).all(|p| p[0].level < p[1].level));
        assert_eq!(levels.last().map(|l| l.depth.size()), Some((side, side)));
        let Some(Event::SetFinished { solution, .. }) = events.last() else {
            panic!("last event is {}", kind(events.last()));
        };
        assert_eq!(solution.depth.size(), (side, side));
        assert_eq!(solution.photos.len(), crate::test_sets::PHOTOS);
        let object = request.problem.object_mask.as_ref().expect("mask.png read");
        let on_object = |k: usize| *object.as_slice().get(k).unwrap_or(&false);
        let solved = solution
            .depth
            .as_slice()
            .iter()
            .zip(solution.normals.as_slice())
            .zip(solution.albedo.as_slice())
            .enumerate()
            .filter(|(k, ((z, n), a))| {
                on_object(*k) && z.is_finite() && **z > 0.0 && n[2].is_finite() && a.is_finite()
            })
            .count();
        let inside = object.as_slice().iter().filter(|&&o| o).count();
        assert!(
            solved * 10 > inside * 9,
            "{solved} of {inside} object pixels solved"
        );
        // A newer set supersedes it; a cancelled one says so.
        let old = worker.submit_set(request.clone());
        worker.cancel(old);
        let events = events_until_end(&mut worker, old);
        assert!(
            matches!(events.last(), Some(Event::Cancelled { .. })),
            "{}",
            kind(events.last())
        );
        // A set that cannot be solved fails with a message; the worker lives on.
        let mut broken = request;
        broken.problem.photos.truncate(1);
        let job = worker.submit_set(broken);
        let error = failure(events_until_end(&mut worker, job).last()).to_owned();
        assert!(error.contains("at least 2"), "{error}");
        let job = worker.submit(sombrero_request(32));
        assert!(finished(events_until_end(&mut worker, job).last()));
    }
}
