"""Talking to models: the OpenAI-compatible client, endpoint configuration and a loopback fake server for tests."""

from jarvis_pytest.llm.client import ChatClient, ChatResult, image_part, system_message, text_part, user_message

__all__ = ["ChatClient", "ChatResult", "image_part", "system_message", "text_part", "user_message"]
