"""The cloud's visual map on the server: keyframes stored per sub-map (database rows and
files), ingested off the request path by a bounded queue, and relocalisation against
them. The work itself is ``maps.domain.keyframes`` and ``maps.domain.relocalisation``."""
