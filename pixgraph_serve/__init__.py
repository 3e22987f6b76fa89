"""``pixgraph serve``: a local HTTP API and browser UI over one ``Session``.

``state.ServeState`` holds the session, the edited graph and the limits (no HTTP);
``app.create_app`` is the Starlette application; ``scene`` turns the UI's light and
background handles into param edits; ``static/`` is the single page.
"""
