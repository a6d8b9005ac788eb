//! The one thread pool of a context and the renderers that draw its scenes.

use std::sync::Arc;

use crate::{CoreError, RENDER_STACK_BYTES, check_threads};

/// A rayon pool shared by everything that runs in parallel: rendering
/// ([`Renderer::with_pool`](crate::Renderer::with_pool)), the commit (fast
/// builds, instance records, the top-level BSP) and the background SAH
/// builds (at most [`MAX_PROMOTIONS_IN_FLIGHT`](crate::MAX_PROMOTIONS_IN_FLIGHT)
/// at once). Its threads wait between frames; nothing spawns a thread per
/// frame. Each thread has a stack of [`RENDER_STACK_BYTES`] for the deepest
/// shading recursion. Cloning shares the pool.
#[derive(Clone)]
pub struct ThreadPool {
    inner: Arc<rayon::ThreadPool>,
}

impl std::fmt::Debug for ThreadPool {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ThreadPool").field("threads", &self.threads()).finish()
    }
}

impl ThreadPool {
    /// A pool of `threads` threads.
    ///
    /// # Errors
    /// [`CoreError::Limit`] for 0 or more than [`MAX_THREADS`](crate::MAX_THREADS)
    /// threads; [`CoreError::RenderThread`] when the system refuses a thread.
    pub fn new(threads: usize) -> Result<Self, CoreError> {
        check_threads("ThreadPool::new", threads)?;
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .stack_size(RENDER_STACK_BYTES)
            .thread_name(|i| format!("openrt-{i}"))
            .build()
            .map(|p| Self { inner: Arc::new(p) })
            .map_err(|e| CoreError::RenderThread {
                reason: format!("cannot start a pool of {threads} threads: {e}"),
            })
    }

    /// A pool with one thread per core.
    ///
    /// # Errors
    /// As [`ThreadPool::new`].
    pub fn all_cores() -> Result<Self, CoreError> {
        Self::new(cores())
    }

    /// Number of threads.
    #[must_use]
    pub fn threads(&self) -> usize {
        self.inner.current_num_threads()
    }

    /// `true` when both handles share one pool.
    #[must_use]
    pub fn same(&self, other: &Self) -> bool {
        Arc::ptr_eq(&self.inner, &other.inner)
    }

    /// Runs `f` on the pool's threads: rayon's parallel iterators inside it
    /// use them (as the commit and the renderer do), not rayon's global pool.
    pub fn install<R: Send>(&self, f: impl FnOnce() -> R + Send) -> R {
        self.inner.install(f)
    }

    /// The rayon pool.
    pub(crate) fn rayon(&self) -> &Arc<rayon::ThreadPool> {
        &self.inner
    }
}

/// Cores of this machine (1 when unknown).
pub(crate) fn cores() -> usize {
    std::thread::available_parallelism().map_or(1, std::num::NonZero::get)
}
