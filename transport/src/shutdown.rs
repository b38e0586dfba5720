//! A shutdown signal shared by a role's tasks: fired by SIGINT/SIGTERM in the binary, by hand
//! in tests and benchmarks.

use tokio::sync::watch;

/// Fires the shutdown; dropping it fires it too, so a role never outlives its owner.
#[derive(Debug)]
pub struct ShutdownTrigger(watch::Sender<bool>);

/// Waits for the shutdown; cheap to clone into every task of a role.
#[derive(Debug, Clone)]
pub struct Shutdown(watch::Receiver<bool>);

/// A connected trigger and signal.
pub fn channel() -> (ShutdownTrigger, Shutdown) {
    let (tx, rx) = watch::channel(false);
    (ShutdownTrigger(tx), Shutdown(rx))
}

impl ShutdownTrigger {
    /// Tells every [`Shutdown`] to stop.
    pub fn fire(&self) {
        // Nobody listening any more is fine: then there is nothing left to stop.
        let _ = self.0.send(true);
    }
}

impl Drop for ShutdownTrigger {
    fn drop(&mut self) {
        self.fire();
    }
}

impl Shutdown {
    /// Whether the shutdown has been fired.
    pub fn is_fired(&self) -> bool {
        *self.0.borrow()
    }

    /// Completes once the shutdown is fired (or its trigger is gone).
    pub async fn wait(&mut self) {
        // An error means the trigger was dropped, which also means stop.
        let _ = self.0.wait_for(|fired| *fired).await;
    }

    /// A signal fired by SIGINT or SIGTERM (Ctrl-C elsewhere); must be called inside a tokio
    /// runtime. The name of the signal is logged (`info`) when it arrives.
    pub fn on_signals() -> std::io::Result<Shutdown> {
        let (trigger, shutdown) = channel();
        #[cfg(unix)]
        {
            use tokio::signal::unix::{SignalKind, signal};
            let mut sigint = signal(SignalKind::interrupt())?;
            let mut sigterm = signal(SignalKind::terminate())?;
            tokio::spawn(async move {
                let name = tokio::select! {
                    _ = sigint.recv() => "SIGINT",
                    _ = sigterm.recv() => "SIGTERM",
                };
                tracing::info!("{name} received, shutting down");
                trigger.fire();
            });
        }
        #[cfg(not(unix))]
        tokio::spawn(async move {
            let _ = tokio::signal::ctrl_c().await;
            trigger.fire();
        });
        Ok(shutdown)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[tokio::test]
    async fn fire_wakes_every_clone_and_drop_fires() {
        let (trigger, shutdown) = channel();
        let mut a = shutdown.clone();
        assert!(!a.is_fired());
        let waiter = tokio::spawn(async move { a.wait().await });
        trigger.fire();
        tokio::time::timeout(std::time::Duration::from_secs(5), waiter).await.unwrap().unwrap();
        assert!(shutdown.is_fired());

        let (trigger, mut shutdown) = channel();
        drop(trigger);
        tokio::time::timeout(std::time::Duration::from_secs(5), shutdown.wait()).await.unwrap();
    }
}
