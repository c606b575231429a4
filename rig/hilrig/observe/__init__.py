"""The observers: what watches a run and shows it. The entity paths of a trace (`paths`, a leaf)
and the view parts the dashboards share (`layout`, a leaf): the two modules `dashboards/`
imports; the tracer (`tracer`) and the Arrow batches it sends
(`batches`), the bus measurements it holds (`busmeter`), its sinks (`sinks`), a robot's chain in
3D (`chain`), the dashboards as the rig loads them (`blueprints`: the one way anything of the
rig reaches dashboards/, which never imports the rest of the rig back), the viewer processes
(`viewer`), reading a trace back (`reader`), and checking a dashboard against a trace, as data
(`dashboard_check`) and in a browser (`browser`, and per series `series_check`). It may
import the engine, the plants, the wire, the dashboards and the base, never the session, the apps
or the CLI.
"""
