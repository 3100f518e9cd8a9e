"""``BundleCache`` holds every bundle the robot has fetched, keyed by Map ID, with its
version and ETag. Entering a sub-map asks the server again *conditionally*
(``If-None-Match``): the answer is ``304 Not Modified`` with no body when nothing
changed, so a held map costs one small round trip and is never downloaded again; the
round trip is worth it because an admin may have edited the map, its tags or the
topology since. When the server cannot be reached, a held bundle is used as it is.
"""

from __future__ import annotations

import logging

import httpx

from maps.domain.topology import TagLink
from robots.agent.supervisor.submaps import BundleError, StoredTag, SubMap, submap_from_bundle

logger = logging.getLogger(__name__)


class BundleCache:
    """Bundles fetched over HTTP with the robot's token, kept by Map ID.

    ``http`` is an ``httpx.AsyncClient`` whose base URL is the server and whose headers
    carry ``Authorization: Token ...``. ``downloads`` counts 200 answers, ``revalidated``
    304 answers.
    """

    def __init__(self, http: httpx.AsyncClient) -> None:
        self.http = http
        self.held: dict[str, SubMap] = {}
        self.downloads = 0
        self.revalidated = 0

    async def load(self, map_id: str) -> SubMap:
        """The sub-map ``map_id`` (``building/code``), current as the server has it.

        Asks conditionally when held; falls back to the held copy when the server cannot
        be reached. Raises BundleError when it is neither held nor fetchable.
        """
        held = self.held.get(map_id)
        try:
            response = await self._get(map_id, held)
        except httpx.HTTPError as error:
            if held is None:
                raise BundleError(f"{map_id}: {error!r}") from None
            logger.warning("bundle %s: %r; using the held copy", map_id, error)
            return held
        return self._stored(map_id, held, response)

    async def _get(self, map_id: str, held: SubMap | None) -> httpx.Response:
        building, _, code = map_id.partition("/")
        headers = {"If-None-Match": held.etag} if held is not None else {}
        url = f"/api/buildings/{building}/maps/{code}/bundle"
        return await self.http.get(url, headers=headers)

    def _stored(self, map_id: str, held: SubMap | None, response: httpx.Response) -> SubMap:
        if response.status_code == 304 and held is not None:
            self.revalidated += 1
            return held
        if response.status_code != 200:
            raise BundleError(f"{map_id}: HTTP {response.status_code}")
        submap = submap_from_bundle(response.json(), response.headers.get("ETag", ""))
        logger.info("bundle %s downloaded (%s)", map_id, "changed" if held else "new")
        self.downloads += 1
        self.held[map_id] = submap
        return submap

    def find_tag(self, building: str, marker_id: int, first: SubMap | None) -> StoredTag | None:
        """The stored tag ``marker_id`` of ``building`` from any held bundle, ``first``'s
        preferred (marker ids are unique in a building)."""
        maps = [first] if first is not None else []
        maps += [m for m in self.held.values() if m.building == building]
        return next((m.tags[marker_id] for m in maps if marker_id in m.tags), None)

    def tag_links(self, building: str) -> list[TagLink]:
        """Every tag of ``building`` that a held bundle stores, as the router wants them."""
        return [
            TagLink(tag.marker_id, tag.submap, tag.links_to)
            for submap in self.held.values()
            if submap.building == building
            for tag in submap.tags.values()
        ]
