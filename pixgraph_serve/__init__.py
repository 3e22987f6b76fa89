"""``pixgraph serve``: a local HTTP API and browser page over one ``Session``.

``state.ServeState`` holds the session, the edited graph and the limits (no HTTP);
``app`` is the Starlette application (route handlers at module level) behind
``guard.Guard`` (what keeps other web pages out); ``runs`` keeps run ids and their
encoded outputs; ``scene`` turns the handles nodes declare into what the page draws
and the param edits a drag means; ``server`` binds and stops; ``cli`` is the command
line; ``errors`` maps every exception to its HTTP status; ``static/`` is the page.
Importing this package imports nothing else (``pixgraph serve`` comes from
``pixgraph_serve.cli``; ``pip install 'pixgraph[serve]'`` brings the web server).
"""
