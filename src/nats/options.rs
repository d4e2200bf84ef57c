//! How the server and the workers connect to NATS: credentials (`--nats-creds`, a `.creds` file
//! of a NATS user: its JWT and NKey seed, as `nsc` writes it), TLS (`--nats-tls-ca`, the
//! certificate authority to trust; the connection then requires TLS, also for a `nats://` URL),
//! and the `max_deliver` of the workers' consumer when this process creates it.

use std::path::PathBuf;
use std::time::Duration;

/// The connection settings.
#[derive(Clone, Debug)]
pub struct NatsOptions {
    /// A NATS credentials file.
    pub creds: Option<PathBuf>,
    /// A PEM file of the certificate authorities that sign the NATS server's certificate.
    pub tls_ca: Option<PathBuf>,
    /// Deliveries of a shard before its study fails (see [`super::poison`]).
    pub max_deliver: i64,
    /// Copies of the shard stream, when this process creates it (a JetStream cluster's servers
    /// keep one each).
    pub replicas: usize,
}

impl Default for NatsOptions {
    fn default() -> Self {
        NatsOptions {
            creds: None,
            tls_ca: None,
            max_deliver: super::poison::DEFAULT_MAX_DELIVER,
            replicas: 1,
        }
    }
}

impl NatsOptions {
    /// The client's connect options, or why they cannot be made (an unreadable credentials
    /// file, a missing CA file).
    pub async fn connect_options(&self) -> Result<async_nats::ConnectOptions, String> {
        let mut options = match &self.creds {
            Some(path) => async_nats::ConnectOptions::with_credentials_file(path)
                .await
                .map_err(|e| format!("cannot read the NATS credentials {}: {e}", path.display()))?,
            None => async_nats::ConnectOptions::new(),
        };
        if let Some(ca) = &self.tls_ca {
            if !ca.is_file() {
                return Err(format!(
                    "the NATS TLS CA file {} does not exist",
                    ca.display()
                ));
            }
            options = options.add_root_certificates(ca.clone()).require_tls(true);
        }
        Ok(options.connection_timeout(Duration::from_secs(5)))
    }
}
