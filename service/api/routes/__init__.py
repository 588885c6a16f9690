"""One router per resource; ``service.api.app`` combines them."""
