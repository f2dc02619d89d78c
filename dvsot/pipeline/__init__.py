"""From inputs to dataset files: a scene rendered (generate), frames you have (simulate), the frames -> events ->
file loop both share (sequence), and many scenes at once (many_scenes, run by scene_runner)."""
