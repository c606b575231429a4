"""Rerun blueprints (layouts) for the rig's traces, one per use; see joint.py."""

from dashboards.joint import BLUEPRINTS, blueprint, named_fields

__all__ = ["BLUEPRINTS", "blueprint", "named_fields"]
