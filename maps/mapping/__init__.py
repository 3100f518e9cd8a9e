"""Mapping sessions: robots build sub-maps in the cloud (see ``sessions`` and ``runner``)."""
