"""Hostile requests to the HTTP side: bodies, heavy answers and absurd tag sizes.

Live tests send real requests to daphne in its own process; the peak of the server's
memory is sampled while they run.
"""

from __future__ import annotations

import http.client
import signal
import socket
import threading
import time
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager

import psutil
import pytest
from asgiref.testing import ApplicationCommunicator

from cloudnav_django.heavy import HeavyBudget, Overloaded
from maps.domain.tagart import MAX_SIZE
from tests.conftest import client_for, make_robot, make_submap, make_tag, map_pgm
from tests.fixtures_live import LiveServer, session_cookie
from tests.support.http_scopes import get, http_scope
from tests.support.uploads import basic, request

pytestmark = pytest.mark.django_db(transaction=True)

MEMORY_BOUND = 64 * 2**20
UPLOAD = "/api/buildings/boccioni_1/maps/"


@contextmanager
def peak_memory(server: LiveServer) -> Iterator[list[int]]:
    """Sample the server's resident memory every 5 ms; yield [growth of the peak]."""
    process = psutil.Process(server.process.pid)
    base = process.memory_info().rss
    peak = [base]
    done = threading.Event()

    def sample() -> None:
        while not done.is_set():
            peak[0] = max(peak[0], process.memory_info().rss)
            time.sleep(0.005)

    sampler = threading.Thread(target=sample)
    sampler.start()
    growth = [0]
    try:
        yield growth
    finally:
        done.set()
        sampler.join()
        growth[0] = peak[0] - base


# ---------------------------------------------------------------- request bodies


def test_anonymous_bodies_are_refused_before_they_are_read(daphne_server, building):
    body = b"x" * (24 * 2**20)
    headers = {"Content-Type": "application/octet-stream"}
    with peak_memory(daphne_server) as growth, ThreadPoolExecutor(6) as pool:
        answers = list(
            pool.map(lambda _: request(daphne_server, "POST", UPLOAD, body, headers), range(6))
        )
    for status, _, text in answers:
        assert status == 401
        assert b"Sign in" in text
    assert growth[0] < MEMORY_BOUND


def test_a_small_anonymous_body_still_reaches_the_sign_in(daphne_server, building):
    status, _, _ = request(daphne_server, "GET", "/accounts/login/")
    assert status == 200
    form = b"username=nobody&password=wrong"
    status, _, text = request(
        daphne_server,
        "POST",
        "/accounts/login/",
        form,
        {"Content-Type": "application/x-www-form-urlencoded"},
    )
    assert status == 403  # Django's CSRF check answers: the body reached Django
    assert b"CSRF" in text


def test_a_signed_in_upload_passes_the_gate(daphne_server, building):
    boundary = "cloudnavboundary"
    parts = [
        ("code", None, b"Gate"),
        ("image", "map.pgm", map_pgm()),
        (
            "yaml",
            "map.yaml",
            b"image: map.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n"
            b"occupied_thresh: 0.65\nfree_thresh: 0.196\nnegate: 0\n",
        ),
    ]
    body = (
        b"".join(
            f'--{boundary}\r\nContent-Disposition: form-data; name="{name}"'.encode()
            + (f'; filename="{filename}"'.encode() if filename else b"")
            + b"\r\n\r\n"
            + content
            + b"\r\n"
            for name, filename, content in parts
        )
        + f"--{boundary}--\r\n".encode()
    )
    headers = {"Content-Type": f"multipart/form-data; boundary={boundary}", **basic("admin")}
    status, _, text = request(daphne_server, "POST", UPLOAD, body * 1 + b"", headers)
    assert status == 201, text


def test_a_body_past_the_limit_is_refused_with_credentials_too(daphne_servers, building):
    server = daphne_servers.start(env={"CLOUDNAV_MAX_BODY_BYTES": str(2**20)})
    headers = {"Content-Type": "application/octet-stream", **basic("admin")}
    status, _, _ = request(server, "POST", UPLOAD, b"x" * (2 * 2**20), headers)
    assert status == 413


def test_a_body_of_unknown_length_needs_credentials(daphne_server, building):
    with socket.create_connection((daphne_server.host, daphne_server.port), timeout=10) as raw:
        raw.sendall(
            f"POST {UPLOAD} HTTP/1.1\r\nHost: 127.0.0.1\r\n"
            "Transfer-Encoding: chunked\r\n\r\n5\r\nhello\r\n0\r\n\r\n".encode()
        )
        assert raw.recv(100).startswith(b"HTTP/1.1 401")


# ---------------------------------------------------------------- heavy answers


def test_the_budget_answers_429_past_a_clients_share_and_503_past_the_process():
    budget = HeavyBudget(slots=2, memory=100, per_client=1)
    first = budget.take("alice", 40)
    with pytest.raises(Overloaded) as own_share:
        budget.take("alice", 1)
    assert own_share.value.status_code == 429
    assert own_share.value.wait
    second = budget.take("bob", 40)
    with pytest.raises(Overloaded) as whole:
        budget.take("carol", 1)
    assert whole.value.status_code == 503
    assert whole.value.wait
    first.release()
    first.release()  # twice is once
    with pytest.raises(Overloaded) as memory:
        budget.take("carol", 61)
    assert memory.value.status_code == 503
    third = budget.take("carol", 60)
    assert budget.in_progress == 2
    second.release()
    third.release()
    assert budget.used_memory == 0


def test_a_request_larger_than_the_whole_budget_is_refused_without_retry():
    with pytest.raises(Overloaded) as refused:
        HeavyBudget(slots=2, memory=100, per_client=1).take("alice", 101)
    assert refused.value.status_code == 503
    assert refused.value.wait is None


def test_a_big_grid_held_by_a_slow_reader_keeps_its_clients_share_until_taken(
    daphne_servers, building
):
    server = daphne_servers.start(env={"CLOUDNAV_HEAVY_PER_CLIENT": "1"})
    make_submap(building, code="Big", image=map_pgm(3000, 3000))  # a 27 MB answer
    path = "/api/buildings/boccioni_1/maps/Big/grid"
    credentials = basic("admin")
    slow = socket.create_connection((server.host, server.port), timeout=10)
    lines = [f"GET {path} HTTP/1.1", "Host: 127.0.0.1"]
    lines += [f"{k}: {v}" for k, v in credentials.items()]
    slow.sendall(("\r\n".join(lines) + "\r\n\r\n").encode())
    assert slow.recv(4096).startswith(b"HTTP/1.1 200")  # then it reads no more
    status, headers, _ = request(server, "GET", path, headers=credentials)
    assert status == 429
    assert headers["Retry-After"]
    status, _, grid = request(server, "GET", path, headers=basic("viewer"))
    assert status == 200
    assert grid.endswith(b"]}")
    slow.close()
    deadline = time.monotonic() + 10
    while request(server, "GET", path, headers=credentials)[0] != 200:
        assert time.monotonic() < deadline, "the slow reader's share was never given back"
        time.sleep(0.1)


def test_a_tag_sheet_larger_than_the_whole_budget_is_refused(daphne_servers, building):
    server = daphne_servers.start(env={"CLOUDNAV_HEAVY_MEMORY_BYTES": str(8 * 2**20)})
    make_tag(make_submap(building))
    status, headers, _ = request(
        server, "GET", "/api/buildings/boccioni_1/tags/print.pdf", headers=basic("viewer")
    )
    assert status == 503
    assert "Retry-After" not in headers


# ---------------------------------------------------------------- tag sizes


@pytest.mark.parametrize("size", [MAX_SIZE * 1.01, 5.0, 1e9])
def test_a_tag_of_absurd_size_is_refused_on_the_api(building, admin, size):
    submap = make_submap(building)
    answer = client_for(admin).post(
        "/api/tags/",
        {
            "building": "boccioni_1",
            "submap": submap.code,
            "marker_id": 3,
            "x": 1.0,
            "y": 1.0,
            "yaw": 0.0,
            "size": size,
            "links_to": submap.code,
        },
        format="json",
    )
    assert answer.status_code == 400
    assert "size" in answer.json()


def test_a_tag_stored_too_large_is_not_printed(building, viewer):
    tag = make_tag(make_submap(building), size=3.0)
    for extension in ("png", "pdf"):
        answer = client_for(viewer).get(f"/api/tags/{tag.pk}/print.{extension}")
        assert answer.status_code == 400


# ---------------------------------------------------------------- video encoders


CAMERA = "/r1/camera/image/compressed"


@pytest.fixture
def watcher(building, viewer):
    make_robot(name="r1", buildings=[building])
    return {"Cookie": session_cookie(viewer).decode()}


async def test_vp8_at_the_largest_size_is_refused_past_the_video_budget(watcher, settings):
    settings.CLOUDNAV_VIDEO_ENCODER_MEMORY_BYTES = 64 * 2**20
    huge = await get(
        "/stream", {"topic": CAMERA, "type": "vp8", "width": "4096", "height": "4096"}, watcher
    )
    assert huge.status == 503
    assert "retry-after" not in huge.headers
    usual = await get("/stream", {"topic": CAMERA, "type": "vp8"}, watcher)
    assert usual.status == 200


async def test_encoders_past_a_clients_share_are_429_and_a_shared_one_costs_nothing(
    watcher, settings
):
    settings.CLOUDNAV_VIDEO_ENCODER_PER_CLIENT = 1
    query = {"topic": CAMERA, "type": "vp8", "bitrate": "200000"}
    first = ApplicationCommunicator(application(), http_scope("/stream", query, watcher))
    await first.send_input({"type": "http.request", "body": b"", "more_body": False})
    assert (await first.receive_output(5))["status"] == 200
    await first.receive_output(5)  # the first body bytes: the encoder is running
    other = await get("/stream", {**query, "bitrate": "300000"}, watcher)
    assert other.status == 429
    assert other.headers["retry-after"]
    same = await get("/stream", query, watcher)
    assert same.status == 200
    await first.send_input({"type": "http.disconnect"})
    await first.wait(5)
    again = await get("/stream", {**query, "bitrate": "300000"}, watcher)
    assert again.status == 200


def application():
    from cloudnav_web.asgi import application

    return application


# ---------------------------------------------------------------- slow headers


def open_until_closed(sock: socket.socket, deadline: float) -> float:
    """Send a header byte each 0.5 s until the server closes ``sock`` (or ``deadline``
    seconds pass); return how long it stayed open."""
    began = time.monotonic()
    sock.settimeout(0.5)
    while time.monotonic() - began < deadline:
        try:
            sock.sendall(b"X")
            if sock.recv(1024) == b"":
                break
        except TimeoutError:
            continue
        except OSError:  # reset by the server
            break
    return time.monotonic() - began


def test_a_request_sent_in_time_to_a_stalled_server_is_served_when_it_wakes(daphne_servers):
    """A server held up (a busy machine, a long pause) past a kept-alive connection's header
    deadline reads the request that came in time before it judges the deadline."""
    server = daphne_servers.start(env={"CLOUDNAV_HEADER_SECONDS": "2"})
    connection = http.client.HTTPConnection(server.host, server.port, timeout=20)
    connection.request("GET", "/api/")
    connection.getresponse().read()  # kept alive: the next request's deadline runs
    server.process.send_signal(signal.SIGSTOP)
    try:
        time.sleep(0.5)
        connection.request("GET", "/api/")  # within the deadline, into the kernel's buffer
        time.sleep(3.0)  # the server wakes past the deadline
    finally:
        server.process.send_signal(signal.SIGCONT)
    answer = connection.getresponse()
    answer.read()
    assert answer.status < 500
    connection.close()


def test_a_client_sending_its_headers_slowly_is_cut_off(daphne_servers):
    server = daphne_servers.start(env={"CLOUDNAV_HEADER_SECONDS": "2"})
    with socket.create_connection((server.host, server.port), timeout=5) as slow:
        slow.sendall(b"GET /api/ HTTP/1.1\r\nHost: localhost\r\nX-Slow: ")
        assert open_until_closed(slow, deadline=15) < 10
    # Quick clients are served as before, on a kept-alive connection too.
    connection = http.client.HTTPConnection(server.host, server.port, timeout=10)
    for _ in range(2):
        connection.request("GET", "/api/")
        answer = connection.getresponse()
        answer.read()
        assert answer.status < 500  # any answer: it was served
        time.sleep(0.1)
    connection.close()
