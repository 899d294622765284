"""The picture of a motion: a :class:`~appell.view.View` evaluated along a simulated motion
(:mod:`.scene`) and played by a three.js viewer on a page (:mod:`.page`)."""

from appell.io.viewer.page import viewer_fragment, viewer_page
from appell.io.viewer.scene import scene_data

__all__ = ["scene_data", "viewer_fragment", "viewer_page"]
