"""The front of the scaled mode: an nginx configuration for N daphne processes behind one port.

``python -m cloudnav_web.front --listen 127.0.0.1:8000 --dir var/nginx 127.0.0.1:8001 ...``
writes ``DIR/nginx.conf``; ``nginx -p DIR -c DIR/nginx.conf`` then runs in the foreground as
the user who starts it, with every path it writes (pid, logs, temporary files) under DIR.
``make demo-scaled`` and the tests' ``front`` fixture both start nginx from this file.
"""

from __future__ import annotations

import argparse
import getpass
import os
from pathlib import Path

UPSTREAM_HEADER = "X-CloudNav-Upstream"
"""Names the daphne process that answered (``host:port``), when ``show_upstream`` is set:
the tests use it to find, and kill, the process holding a robot's socket."""

TEMPORARY = ("client_body", "proxy", "fastcgi", "uwsgi", "scgi")


def nginx_config(
    upstreams: list[str], listen: str, directory: Path, show_upstream: bool = False
) -> str:
    """Return an nginx.conf that spreads HTTP and WebSocket connections over ``upstreams``
    (``host:port`` of daphne processes) and listens on ``listen`` (``host:port``).

    ``least_conn``: a robot's or page's WebSocket lasts hours, so new ones go to the
    process holding the fewest, and a process that refuses connections (killed, restarting)
    is skipped for 5 s while the others take its share.
    """
    directory = directory.resolve()
    servers = "\n".join(f"    server {u} max_fails=1 fail_timeout=5s;" for u in upstreams)
    temporary = "\n".join(f"  {kind}_temp_path {directory / kind};" for kind in TEMPORARY)
    upstream_header = (
        f"      add_header {UPSTREAM_HEADER} $upstream_addr always;\n" if show_upstream else ""
    )
    return f"""# Written by cloudnav_web/front.py; edits are overwritten.
{_user_line()}worker_processes 1;
daemon off;
pid {directory / "nginx.pid"};
error_log {directory / "error.log"} warn;
events {{ worker_connections 4096; }}
http {{
  # daphne logs each request (robot tokens redacted); nginx adds only its errors.
  access_log off;
{temporary}
  # The application enforces its own body limits (and says which in its 413).
  client_max_body_size 0;
  map $http_upgrade $connection_upgrade {{ default upgrade; '' close; }}
  upstream cloudnav {{
    least_conn;
{servers}
  }}
  server {{
    listen {listen};
    location / {{
      proxy_pass http://cloudnav;
      proxy_http_version 1.1;
      proxy_set_header Upgrade $http_upgrade;
      proxy_set_header Connection $connection_upgrade;
      # The origin check compares a page's Origin with the host and port it reached.
      proxy_set_header Host $http_host;
      proxy_set_header X-Forwarded-For $remote_addr;
      # Live streams (MJPEG, WebM) and uploads pass through as they come.
      proxy_buffering off;
      proxy_request_buffering off;
      proxy_read_timeout 1d;
      proxy_send_timeout 1d;
{upstream_header}    }}
  }}
}}
"""


def _user_line() -> str:
    # Started as root, nginx would run its worker as nobody, which cannot write DIR.
    return f"user {getpass.getuser()};\n" if os.geteuid() == 0 else ""


def write_config(
    upstreams: list[str], listen: str, directory: Path, show_upstream: bool = False
) -> Path:
    """Write ``directory/nginx.conf`` (creating the directory) and return its path."""
    directory.mkdir(parents=True, exist_ok=True)
    path = directory / "nginx.conf"
    path.write_text(nginx_config(upstreams, listen, directory, show_upstream))
    return path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--listen", required=True, help="host:port of the public side")
    parser.add_argument("--dir", required=True, type=Path, help="where nginx keeps its files")
    parser.add_argument("upstreams", nargs="+", help="host:port of each daphne process")
    arguments = parser.parse_args()
    print(write_config(arguments.upstreams, arguments.listen, arguments.dir))


if __name__ == "__main__":
    main()
