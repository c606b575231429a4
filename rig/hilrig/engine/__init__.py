"""The engine: what runs cycles against a node. The driver (`driver`) and its history
(`history`), the lockstep and real-time drivers as siblings (`lockstep`, `realtime`), the cycle
runner (`timeline`), the observers' interface (`observers`), the Rig that puts a plant on a node
(`rig`) and the robot of several modules (`robot`). It imports the layers below it only: the
wire, the plants and the base of hilrig; observers come in through `RigObserver`, never by name.
"""
