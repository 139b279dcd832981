"""The tool <-> PC link: the Articutool API over Zenoh with ROS 2 CDR messages (issue 4).

Modules: ``messages`` (interfaces, CDR codecs, conversions), ``transport`` (interface and the
rmw_zenoh-style key mapping), ``zenoh_transport`` / ``memory_transport`` (implementations),
``server`` (tool side: ``ToolServer``, ``serve_forever``), ``client`` (PC side:
``ArticutoolClient``), ``config`` (``LinkConfig``) and ``cli`` (``articutool client``).
Nothing is imported here so ``import articutool.link`` stays cheap (zenoh loads on use).
"""
