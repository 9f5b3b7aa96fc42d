"""The lab: what a class does with the robots and the LMS — exercises, their attempts and grades.

Rooms: exercises as data, read from ``--exercises-dir`` (``exercises``: ``Library``, ``parse``);
goals as evaluators (``goals``, pure); a live attempt watched on the station's own topics
(``checker``) and its result kept (``results``: table ``exercise_attempts``); scores back to the
LMS through a persisted outbox (``grades``: LTI Advantage AGS); the courses' members read from the
LMS (``roster``: NRPS, kept in ``auth.courses``); who an admin may book for (``people``); where a
launch lands and what a teacher's deep-linking pick adds to the course (``landing``); the program
library's files (``programs``); the robots' block sets and the class's shared blocks (``blocks``),
checked as data against the IDE's block schema (``blockcheck``). HTTP for all of them is in ``web/``.

Who someone is (tokens, sign-in, the LTI launch's identity) is ``auth``'s; whether they may is the
rules'; the lab sits above both.

May import: ``rules``, ``auth``, ``store`` and ``settings``; never ``bridge``, ``runs``, ``media``,
``twin`` or ``web`` (its doors, the topics and a recorder, are handed in: ``checker``).
"""
