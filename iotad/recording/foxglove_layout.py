"""The Foxglove layout that opens the robot ready to watch (docs/foxglove-layout.json), built
with foxglove-sdk's layout types: the 3D scene (the arm's model moving in its frames, Buggy's
arena, path and pose, the conveyor's belt, bin and cubes), the arm's joint positions plotted, and /log. `iotad view` serves and
`iotad export --json` writes exactly the topics it names (iotad/recording/foxglove_scene.py)."""
from __future__ import annotations

from iotad.recording.foxglove_scene import ARENA, ARM_JOINTS, ARM_MODEL, CONVEYOR, PATH, POSE, WORLD

LOG_TOPIC = "/log"  # iotad/recording/foxglove_mapping.py's


def layout_json() -> str:
    from foxglove.layouts import (BaseRendererPoseTopicSettings, BaseRendererSceneUpdateTopicSettings, Layout,
                                  LogConfig, LogPanel, PlotConfig, PlotPanel, PlotSeries, SplitContainer, SplitItem,
                                  ThreeDeeConfig, ThreeDeePanel)

    scene = ThreeDeePanel(title="robot", config=ThreeDeeConfig(
        fixed_frame=WORLD, follow_tf=WORLD, follow_mode="follow-none",
        topics={ARM_MODEL: BaseRendererSceneUpdateTopicSettings(visible=True),
                ARENA: BaseRendererSceneUpdateTopicSettings(visible=True),
                CONVEYOR: BaseRendererSceneUpdateTopicSettings(visible=True),
                PATH: BaseRendererSceneUpdateTopicSettings(visible=True),
                POSE: BaseRendererPoseTopicSettings(visible=True)}))
    joints = PlotPanel(title="arm joints (rad)", config=PlotConfig(show_legend=True, paths=[
        PlotSeries(value=f"{ARM_JOINTS}.joints[{k}].position", label=f"joint{k + 1}", enabled=True,
                   timestamp_method="receiveTime") for k in range(6)]))
    log = LogPanel(title="acks and violations", config=LogConfig(topic_to_render=LOG_TOPIC))
    content = SplitContainer(direction="row", items=[
        SplitItem(proportion=2, content=scene),
        SplitItem(proportion=1, content=SplitContainer(direction="column", items=[
            SplitItem(proportion=1, content=joints), SplitItem(proportion=1, content=log)]))])
    return Layout(content=content).to_json()
