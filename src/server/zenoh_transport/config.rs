//! The `[zenoh]` section of the server settings: how the server joins the Zenoh network.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::pipeline::ConfigError;

/// Role of the server in the Zenoh network.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum ZenohMode {
    /// Talks directly to the peers it connects to or that connect to it (no router needed).
    Peer,
    /// Talks through the router(s) in `connect` only.
    Client,
    /// Routes for others as well (a small deployment without a separate router).
    Router,
}

impl ZenohMode {
    /// The name Zenoh's own configuration uses.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Peer => "peer",
            Self::Client => "client",
            Self::Router => "router",
        }
    }
}

/// How the server joins Zenoh. The default is an embedded peer listening on loopback only, with
/// multicast scouting off: nothing outside this machine can reach it until `listen` or `connect`
/// says otherwise.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct ZenohConfig {
    /// Whether `avsep serve` joins Zenoh at start-up (sessions then also stream over Zenoh).
    pub enabled: bool,
    /// Role in the Zenoh network: `peer`, `client` (needs a router in `connect`) or `router`.
    pub mode: ZenohMode,
    /// Zenoh endpoints to connect to at start-up (routers or peers), e.g. `tcp/10.0.0.5:7447`.
    pub connect: Vec<String>,
    /// Zenoh endpoints to listen on, e.g. `tcp/0.0.0.0:7447` to accept edge devices from the
    /// network. The default accepts connections from this machine only.
    pub listen: Vec<String>,
    /// Discover other Zenoh nodes by UDP multicast (off by default: endpoints are explicit).
    pub multicast_scouting: bool,
    /// Session-management queries (create, list, inspect) waiting to be served; more are answered
    /// with a `busy` error at once.
    pub query_queue: usize,
}

impl Default for ZenohConfig {
    fn default() -> Self {
        Self {
            enabled: true,
            mode: ZenohMode::Peer,
            connect: Vec::new(),
            listen: vec!["tcp/127.0.0.1:7447".into()],
            multicast_scouting: false,
            query_queue: 16,
        }
    }
}

impl ZenohConfig {
    /// Checks every field; the error names the first bad one (with the `zenoh.` prefix).
    pub fn validate(&self) -> Result<(), ConfigError> {
        for (name, list) in [("connect", &self.connect), ("listen", &self.listen)] {
            for (i, e) in list.iter().enumerate() {
                if let Err(err) = e.parse::<zenoh::config::EndPoint>() {
                    return Err(ConfigError::new(
                        format!("zenoh.{name}[{i}]"),
                        format!("{e:?} is not a Zenoh endpoint such as tcp/127.0.0.1:7447: {err}"),
                    ));
                }
            }
        }
        if self.enabled && self.mode == ZenohMode::Client && self.connect.is_empty() {
            return Err(ConfigError::new(
                "zenoh.connect",
                "client mode needs at least one router to connect to",
            ));
        }
        if self.query_queue == 0 {
            return Err(ConfigError::new("zenoh.query_queue", "must be at least 1"));
        }
        Ok(())
    }

    /// The Zenoh configuration these settings describe.
    pub fn to_zenoh(&self) -> Result<zenoh::Config, ConfigError> {
        let mut c = zenoh::Config::default();
        let mut set = |key: &str, value: serde_json::Value| {
            c.insert_json5(key, &value.to_string())
                .map_err(|e| ConfigError::new("zenoh", format!("{key}: {e}")))
        };
        set("mode", self.mode.as_str().into())?;
        set("connect/endpoints", self.connect.clone().into())?;
        set("listen/endpoints", self.listen.clone().into())?;
        set("scouting/multicast/enabled", self.multicast_scouting.into())?;
        Ok(c)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_listen_on_loopback_without_scouting() {
        let c = ZenohConfig::default();
        c.validate().unwrap();
        assert_eq!(c.mode, ZenohMode::Peer);
        assert!(c.listen.iter().all(|e| e.starts_with("tcp/127.0.0.1:")));
        assert!(!c.multicast_scouting && c.connect.is_empty());
        let z = c.to_zenoh().unwrap();
        assert_eq!(z.get_json("scouting/multicast/enabled").unwrap(), "false");
        assert!(
            z.get_json("listen/endpoints")
                .unwrap()
                .contains("127.0.0.1:7447")
        );
    }

    #[test]
    fn bad_endpoints_and_modes_name_the_field() {
        let c = ZenohConfig {
            listen: vec!["tcp/127.0.0.1:7447".into(), "nonsense".into()],
            ..Default::default()
        };
        assert_eq!(c.validate().unwrap_err().field, "zenoh.listen[1]");
        let c = ZenohConfig {
            mode: ZenohMode::Client,
            ..Default::default()
        };
        assert_eq!(c.validate().unwrap_err().field, "zenoh.connect");
        let c = ZenohConfig {
            query_queue: 0,
            ..Default::default()
        };
        assert_eq!(c.validate().unwrap_err().field, "zenoh.query_queue");
    }
}
