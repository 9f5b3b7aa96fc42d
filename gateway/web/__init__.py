"""The HTTP side: the tornado application with every route in one place (``app``), the rosbridge
websocket (``socket``), the pages and what the HTTP side lets through (``pages``), the JSON API
base (``api``) and its apps: the program library, robot-side runs, recordings and playback, the
teacher's class view, and signing in (``login``; ``lti``: launches from an LMS; ``cookies``: the
cookie attributes browsers need in and out of an LMS's iframe); what the process logs, scrubbed of tokens and forged
lines (``logs``).

May import: ``bridge``, ``rules``, ``backends`` (types), ``protocol``, ``settings``.
"""
