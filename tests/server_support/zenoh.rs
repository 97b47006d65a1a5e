//! An in-process server with its Zenoh transport on a free loopback port.

use std::time::Duration;

use avsep::server::ServerConfig;
use avsep::server::zenoh_transport::{ZenohConfig, ZenohTransport};

use super::TestServer;

/// A server with its Zenoh transport on a free loopback port.
pub struct ZenohServer {
    /// The HTTP side and the registry.
    pub http: TestServer,
    transport: ZenohTransport,
    /// Where the transport listens (`tcp/127.0.0.1:<port>`).
    pub endpoint: String,
}

impl ZenohServer {
    /// The port is found free by binding it and letting it go, so another test's outgoing
    /// connection can take it before Zenoh listens there (seen in CI as "Address already in
    /// use"); a few fresh ports are tried before giving up.
    pub async fn start(cfg: ServerConfig) -> Self {
        let zenoh = cfg.zenoh.clone();
        let http = TestServer::start(cfg).await;
        let mut last = None;
        for _ in 0..5 {
            let port = std::net::TcpListener::bind("127.0.0.1:0")
                .unwrap()
                .local_addr()
                .unwrap()
                .port();
            let endpoint = format!("tcp/127.0.0.1:{port}");
            let zcfg = ZenohConfig {
                listen: vec![endpoint.clone()],
                ..zenoh.clone()
            };
            match ZenohTransport::start(&zcfg, http.registry.clone()).await {
                Ok(transport) => {
                    return Self {
                        http,
                        transport,
                        endpoint,
                    };
                }
                Err(e) => last = Some(e),
            }
        }
        panic!("no free port for the Zenoh transport: {last:?}");
    }

    /// Stops the HTTP side, then leaves Zenoh after the sessions' last messages.
    pub async fn stop(self) {
        self.http.stop().await;
        self.transport.close(Duration::from_secs(2)).await;
    }
}
