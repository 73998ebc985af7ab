"""The 3D browser view (``flexshell view``): a scene's geometry and motion as one self-contained HTML file.

:mod:`shell.view.scene` gathers what to draw from a log, a scenario or a linear model (bodies from
their geometry, node frames, wheels, thrusters, the track, signals) into a :class:`~shell.view.scene.ViewScene`
of plain arrays; :mod:`shell.view.page` writes it with the viewer (``assets/viewer.js``) and three.js
(``assets/three.min.js``, r111 as packaged by Debian, MIT) into one HTML file that opens offline. Flexible
bodies deform in the browser: mode shapes times the logged modal coordinates, per frame, so the file holds
the shapes once and the coordinates per frame instead of every deformed mesh (docs/view.md).
"""
