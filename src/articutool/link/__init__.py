"""The tool <-> PC link: the Articutool API over Zenoh with ROS 2 CDR messages.

Modules: ``messages`` (interfaces, CDR codecs, conversions), ``transport`` (interface and the
rmw_zenoh-style key mapping), ``zenoh_transport`` / ``memory_transport`` (implementations),
``server`` (tool side: ``ToolServer``, ``serve_forever``), ``client`` (PC side:
``ArticutoolClient``), ``config`` (``LinkConfig``), ``pairing`` (``articutool pair``: CA and
device certificates), ``auth`` (signatures and their verification) and ``cli``
(``articutool client``, ``articutool pair``).
Nothing is imported here so ``import articutool.link`` stays cheap (zenoh loads on use).
"""
