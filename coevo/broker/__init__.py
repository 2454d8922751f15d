"""The broker: an embedded Zenoh router plus the policy store (the service issue; not built yet)."""
